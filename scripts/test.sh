#!/usr/bin/env bash
# Run the whole test suite serially and on 2 MPI ranks (installs what is missing first).
# Usage: bash scripts/test.sh [--fast] [extra pytest arguments]
#   --fast: only the tests not marked slow (pytest -m "not slow"), the quick loop while
#           developing; without it everything runs (what CI runs).
set -euo pipefail
cd "$(dirname "$0")/.."
SELECT=()
ARGS=()
for a in "$@"; do
  if [ "$a" = "--fast" ]; then SELECT=(-m "not slow"); else ARGS+=("$a"); fi
done
set -- "${SELECT[@]}" "${ARGS[@]}"
bash scripts/setup.sh
export OMPI_ALLOW_RUN_AS_ROOT=1 OMPI_ALLOW_RUN_AS_ROOT_CONFIRM=1 OPENBLAS_NUM_THREADS=1
export VTK_DEFAULT_OPENGL_WINDOW=vtkEGLRenderWindow
PY=.venv/bin/python
echo "== serial =="
$PY -m pytest -q -p no:cacheprovider "$@" tests
echo "== mpirun -n 2 =="
# rank 1's output is kept in a file, shown only if it fails
mpirun -n 2 --oversubscribe bash -c '
  if [ "$OMPI_COMM_WORLD_RANK" = "0" ]; then exec "$0" "$@";
  else exec "$0" "$@" > .pytest-rank1.log 2>&1; fi' \
  $PY -m pytest -q -p no:cacheprovider "$@" tests || { cat .pytest-rank1.log; exit 1; }
rm -f .pytest-rank1.log
