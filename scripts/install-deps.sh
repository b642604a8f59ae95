#!/usr/bin/env bash
# Install what drape needs on Debian 12, only what is missing.
#   install-deps.sh                 Debian packages (PETSc, Open MPI, HDF5, METIS, CGAL)
#   install-deps.sh --without-petsc METIS, CGAL and the tools, not PETSc, its MPI and HDF5
#                                   (PETSC_DIR names another PETSc; nothing without dpkg)
#   install-deps.sh --petsc64       Debian's PETSc with 64-bit indices (libpetsc64-real3.18-dev)
#   install-deps.sh --python D [R]  a Python virtual environment D with R (scripts/requirements.txt),
#                                   made again when an interrupted earlier run left it incomplete
set -euo pipefail
here=$(cd "$(dirname "$0")" && pwd)

if [ "${1:-}" = "--python" ]; then
  # Made again when an earlier run stopped part-way: a venv without pip (python3 -m
  # venv interrupted), or without the pinned packages, or with files of them missing
  # (pip interrupted). A complete one is left alone, without asking the network.
  venv=${2:-.venv}
  requirements=${3:-$here/requirements.txt}
  [ -r "$requirements" ] || { echo "drape: cannot read the Python requirements file $requirements"; exit 1; }
  complete() {
    "$venv/bin/python" - "$requirements" >/dev/null 2>&1 <<'PY'
import os, sys
from importlib import metadata
import pip  # noqa: F401  (a venv whose creation stopped before ensurepip has none)
for line in open(sys.argv[1]):
    line = line.split("#")[0].strip()
    if not line:
        continue
    name, _, version = line.partition("==")
    dist = metadata.distribution(name.strip())
    if version and dist.version != version.strip():
        sys.exit(1)
    if not all(os.path.exists(dist.locate_file(f)) for f in dist.files or []):
        sys.exit(1)
PY
  }
  make_venv() {
    python3 -m venv --clear "$venv" || { echo "drape: cannot create a Python virtual environment in $venv; install python3-venv (apt-get install python3-venv)"; exit 1; }
  }
  complete && exit 0
  if [ -e "$venv" ] && [ ! -f "$venv/pyvenv.cfg" ] && [ -n "$(ls -A "$venv" | grep -vxE 'bin|include|lib|lib64|share|\.installed')" ]; then
    echo "drape: $venv is not a Python virtual environment (no pyvenv.cfg) and holds other files; remove it, or name another directory with VENV=..."
    exit 1
  fi
  if [ -e "$venv" ] && ! "$venv/bin/python" -c 'import pip' >/dev/null 2>&1; then
    echo "drape: $venv is incomplete (no working python or pip: an earlier run stopped while making it?); making it again"
    make_venv
  elif [ ! -e "$venv" ]; then
    make_venv
  fi
  "$venv/bin/python" -m pip install -q --disable-pip-version-check -r "$requirements" || { echo "drape: pip could not install $requirements into $venv (is the network or a package index reachable?)"; exit 1; }
  complete && exit 0
  echo "drape: $venv still lacks files of the pinned packages after pip install (an earlier run stopped while pip wrote them?); making it again"
  make_venv
  "$venv/bin/python" -m pip install -q --disable-pip-version-check -r "$requirements" || { echo "drape: pip could not install $requirements into $venv (is the network or a package index reachable?)"; exit 1; }
  complete || { echo "drape: $venv lacks packages of $requirements even after it was made again; see pip's messages above"; exit 1; }
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
