#!/usr/bin/env bash
# Install gmsh for baffle-mesh (tetrahedral meshing runs gmsh as a child process):
# the PyPI wheel, plus the X11/OpenGL runtime libraries its libgmsh.so links against
# when the machine lacks them. Idempotent; prints the gmsh version it ends up with.
# baffle-mesh finds gmsh via $BAFFLE_GMSH, then `gmsh` on PATH, then `python3 -c "import gmsh"`.
set -euo pipefail

GMSH_VERSION="${GMSH_VERSION:-4.15.2}"
GMSH_LIBS=(libglu1-mesa libgl1 libopengl0 libxcursor1 libxft2 libxinerama1 libxrender1 libxfixes3 libxext6 libx11-6 libfontconfig1 libgomp1)

if ! python3 -c 'import gmsh' >/dev/null 2>&1; then
    python3 -m pip install --quiet --disable-pip-version-check "gmsh==${GMSH_VERSION}"
fi

# The wheel imports only when libgmsh.so's shared libraries are present.
if ! python3 -c 'import gmsh' >/dev/null 2>&1; then
    export DEBIAN_FRONTEND=noninteractive
    apt-get update -qq
    apt-get install -y -qq --no-install-recommends "${GMSH_LIBS[@]}" >/dev/null
fi

python3 -c 'import gmsh, sys; gmsh.initialize(["gmsh", "--version"], run=True)' 2>&1 | tail -n 1 | sed 's/^/gmsh /'
