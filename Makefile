# pimpm in two commands, on a fresh Debian bookworm clone (as root, or as a
# user with sudo):
#
#   make run    set up whatever is missing, then run the quasi-static billet
#               (inputs/billet.yaml) on 2 ranks into billet_output/
#   make test   set up whatever is missing, then run the whole test suite
#   make test-fast   the same without the tests that run pimpm in subprocesses
#               (mpiexec) or take long (pytest -m "not mpi and not slow")
#
# Both are idempotent; the set-up (scripts/setup.sh: Debian's PETSc stack,
# numba, .venv, the compiled kernels) runs again only when setup.sh or
# pyproject.toml changed. OpenMPI's root guard is lifted for the commands here.

SHELL := /bin/bash
PYTHON := .venv/bin/python
RANKS ?= 2
export OMPI_ALLOW_RUN_AS_ROOT := 1
export OMPI_ALLOW_RUN_AS_ROOT_CONFIRM := 1
export OMPI_MCA_rmaps_base_oversubscribe := 1

.PHONY: run test test-fast setup

run: setup
	mpiexec -n $(RANKS) $(PYTHON) -m pimpm inputs/billet.yaml --overwrite

test: setup
	$(PYTHON) -m pytest -q tests

test-fast: setup
	$(PYTHON) -m pytest -q -m "not mpi and not slow" tests

setup: .venv/.pimpm-setup

.venv/.pimpm-setup: scripts/setup.sh pyproject.toml
	bash scripts/setup.sh
	touch $@
