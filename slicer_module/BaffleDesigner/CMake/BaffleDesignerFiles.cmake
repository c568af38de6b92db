# The scripted module's files, for slicerMacroBuildScriptedModule (CMakeLists.txt) and for
# the package-layout check without Slicer (PackageLayout/), so both install the same.
set(BAFFLE_DESIGNER_PYTHON_SCRIPTS
  BaffleDesigner.py
  BaffleDesignerLib/__init__.py
  BaffleDesignerLib/candidate.py
  BaffleDesignerLib/environment.py
  BaffleDesignerLib/logic.py
  BaffleDesignerLib/plan.py
  BaffleDesignerLib/prepare.py
  BaffleDesignerLib/process.py
  BaffleDesignerLib/report.py
  BaffleDesignerLib/rims.py
  BaffleDesignerLib/simulation.py
  )
set(BAFFLE_DESIGNER_PYTHON_RESOURCES
  Resources/Icons/BaffleDesigner.png
  Resources/UI/BaffleDesigner.ui
  )
