#!/usr/bin/env bash
# Install everything fxcontact needs on Debian 12 (as root), idempotently:
#   Debian's dolfinx 0.5.2 stack + OpenBLAS + MPI, and a venv (.venv, --system-site-packages)
#   holding fxcontact in editable mode with its PyPI extras (numpy pinned to Debian's).
# Usage: bash scripts/setup.sh [--demo]   (--demo: then run the main demo on 2 ranks)
set -euo pipefail
cd "$(dirname "$0")/.."
ROOT=$(pwd)

PKGS="python3-dolfinx-real python3-dolfinx python3-gmsh python3-numba python3-scipy \
python3-pytest python3-venv mpi-default-bin libopenblas0-pthread libegl1 libegl-mesa0 git"
missing=""
for p in $PKGS; do
  dpkg -s "$p" >/dev/null 2>&1 || missing="$missing $p"
done
if [ -n "$missing" ]; then
  echo "[setup] installing Debian packages:$missing"
  SUDO=""; [ "$(id -u)" -ne 0 ] && SUDO="sudo"
  $SUDO apt-get update -qq
  DEBIAN_FRONTEND=noninteractive $SUDO apt-get install -y -qq --no-install-recommends $missing
else
  echo "[setup] Debian packages present"
fi

VENV="$ROOT/.venv"
if [ ! -x "$VENV/bin/python" ]; then
  echo "[setup] creating $VENV"
  /usr/bin/python3 -m venv --system-site-packages "$VENV"
fi
NUMPY=$(/usr/bin/python3 -c "import numpy; print(numpy.__version__)")
STAMP="$VENV/.fxcontact-stamp"
WANT="$(sha256sum pyproject.toml | cut -c1-64) numpy=$NUMPY"
if [ ! -f "$STAMP" ] || [ "$(cat "$STAMP")" != "$WANT" ]; then
  echo "[setup] installing fxcontact (editable) and PyPI extras into $VENV"
  echo "numpy==$NUMPY" > "$VENV/constraints.txt"
  "$VENV/bin/python" -m pip install -q --disable-pip-version-check \
    -c "$VENV/constraints.txt" -e ".[viz,test]"
  echo "$WANT" > "$STAMP"
else
  echo "[setup] venv up to date"
fi
"$VENV/bin/python" -c "import dolfinx, fxcontact; print('[setup] dolfinx', dolfinx.__version__, '| fxcontact', fxcontact.__version__)"

if [ "${1:-}" = "--demo" ]; then
  export OMPI_ALLOW_RUN_AS_ROOT=1 OMPI_ALLOW_RUN_AS_ROOT_CONFIRM=1 OPENBLAS_NUM_THREADS=1
  mpirun -n 2 --oversubscribe "$VENV/bin/python" demos/demo_wire_drawing.py --size 0.4 \
    --t_end 0.1 --vtk_every 10 "${@:2}"
fi
