"""BaffleDesigner's Qt-free parts: the MRML logic (logic.py) and the command line
process runner (process.py)."""
