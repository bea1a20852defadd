#!/usr/bin/env bash
# Set up pimpm on Debian bookworm (or a Debian-based image) with Debian's PETSc 3.18 stack.
# Safe to run twice. Creates ./.venv (system site packages, so Debian's petsc4py/h5py-mpi are used).
set -euo pipefail
cd "$(dirname "$0")/.."

PKGS="python3-petsc4py python3-mpi4py python3-h5py-mpi python3-meshio python3-yaml python3-pytest python3-hypothesis
python3-numpy python3-numba python3-matplotlib python3-venv python3-setuptools python3-pip openmpi-bin"
SUDO=""
[ "$(id -u)" -eq 0 ] || SUDO="sudo"
missing=""
for p in $PKGS; do dpkg -s "$p" >/dev/null 2>&1 || missing="$missing $p"; done
if [ -n "$missing" ]; then
  echo "[setup] installing Debian packages:$missing"
  $SUDO apt-get update -q
  DEBIAN_FRONTEND=noninteractive $SUDO apt-get install -y -q --no-install-recommends $missing
fi

PETSC_PY=/usr/lib/petscdir/petsc3.18/x86_64-linux-gnu-real/lib/python3/dist-packages
[ -d "$PETSC_PY" ] || PETSC_PY=$(ls -d /usr/lib/petscdir/petsc3.*/*-real/lib/python3/dist-packages | head -n 1)

if [ ! -x .venv/bin/python ]; then
  echo "[setup] creating .venv from /usr/bin/python3 (with Debian's site packages)"
  /usr/bin/python3 -m venv --system-site-packages .venv
fi
SITE=$(.venv/bin/python -c 'import sysconfig; print(sysconfig.get_paths()["purelib"])')
echo "$PETSC_PY" > "$SITE/petsc4py-debian.pth"
# --no-deps: Debian provides numpy 1.24/h5py-mpi/petsc4py; PyPI copies would shadow them (PLATFORM.md).
.venv/bin/python -m pip install -q --no-deps --no-build-isolation -e . >/dev/null
.venv/bin/python -c "import petsc4py, mpi4py, h5py, numpy, numba, yaml, meshio; from petsc4py import PETSc; import pimpm; print('[setup] ok: PETSc', '.'.join(map(str, PETSc.Sys.getVersion())), 'numpy', numpy.__version__, 'numba', numba.__version__, 'h5py', h5py.__version__, 'mpi', h5py.get_config().mpi)"
# compile the particle kernels once now (numba; cached on disk), not in the first run
.venv/bin/python -m pimpm.precompile
