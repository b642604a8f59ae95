#!/usr/bin/env bash
# Install what drape needs on Debian 12, only what is missing.
#   install-deps.sh                 Debian packages (PETSc, Open MPI, HDF5, METIS, CGAL)
#   install-deps.sh --without-petsc METIS, CGAL and the tools, not PETSc, its MPI and HDF5
#                                   (PETSC_DIR names another PETSc; nothing without dpkg)
#   install-deps.sh --petsc64       Debian's PETSc with 64-bit indices (libpetsc64-real3.18-dev)
#   install-deps.sh --python D      a Python virtual environment D with scripts/requirements.txt
set -euo pipefail
here=$(cd "$(dirname "$0")" && pwd)

if [ "${1:-}" = "--python" ]; then
  venv=${2:-.venv}
  if [ ! -x "$venv/bin/python" ]; then
    python3 -m venv "$venv" || { echo "drape: cannot create a Python virtual environment; install python3-venv (apt-get install python3-venv)"; exit 1; }
  fi
  "$venv/bin/python" -m pip install -q --disable-pip-version-check -r "$here/requirements.txt"
  exit 0
fi

# libopenblas0-serial: PETSc's BLAS (vector updates, dense solves) through OpenBLAS
# instead of the reference BLAS (single-threaded: MPI ranks own the cores)
packages="petsc-dev libopenblas0-serial libmetis-dev libhdf5-openmpi-dev libcgal-dev pkg-config make g++ clang-format"
case "${1:-}" in
  --without-petsc)
    command -v dpkg >/dev/null || exit 0
    packages="libmetis-dev libcgal-dev pkg-config make g++ clang-format" ;;
  --petsc64) packages="libpetsc64-real3.18-dev" ;;
  "") ;;
  *) echo "drape: install-deps.sh takes --without-petsc, --petsc64 or --python DIR, not '$1'"; exit 1 ;;
esac
command -v dpkg >/dev/null || { echo "drape: no dpkg: this is not a Debian machine; install PETSc (with HDF5), METIS and CGAL yourself and name PETSc with PETSC_DIR and PETSC_ARCH"; exit 1; }
missing=""
for p in $packages; do
  dpkg -s "$p" >/dev/null 2>&1 || missing="$missing $p"
done
[ -z "$missing" ] && exit 0
if [ "$(id -u)" != 0 ]; then
  echo "drape: missing Debian packages:$missing"
  echo "drape: install them with: sudo apt-get install$missing"
  exit 1
fi
echo "drape: installing$missing"
export DEBIAN_FRONTEND=noninteractive
apt-get update -qq
apt-get install -y -qq --no-install-recommends $missing >/dev/null
