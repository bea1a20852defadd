# pimpm on Debian bookworm's PETSc 3.18 stack (petsc4py, mpi4py, h5py-mpi, OpenMPI 4.1).
#   docker build -t pimpm .
#   docker run --rm pimpm                                  # quasi-static billet on 2 ranks
#   docker run --rm -v "$PWD/out:/opt/pimpm/billet_output" pimpm   # keep the results
#   docker run --rm pimpm .venv/bin/python -m pytest -q tests       # the test suite
FROM debian:bookworm-slim

# OpenMPI refuses to start as root without these; the container runs as root.
# oversubscribe: 2 ranks still start when the container gets a single CPU.
# vader single copy (CMA) needs ptrace rights that containers usually lack.
ENV OMPI_ALLOW_RUN_AS_ROOT=1 \
    OMPI_ALLOW_RUN_AS_ROOT_CONFIRM=1 \
    OMPI_MCA_rmaps_base_oversubscribe=1 \
    OMPI_MCA_btl_vader_single_copy_mechanism=none \
    DEBIAN_FRONTEND=noninteractive \
    PYTHONDONTWRITEBYTECODE=1

WORKDIR /opt/pimpm

# What scripts/setup.sh needs (apt packages, then .venv with an editable install
# of the pimpm package); the rest of the repository is copied afterwards so that
# editing tests, inputs or docs does not redo this layer. setup.sh runs apt-get
# directly when it is root (no sudo in the image).
COPY pyproject.toml README.md ./
COPY scripts/ scripts/
COPY pimpm/ pimpm/
RUN bash scripts/setup.sh \
 && apt-get clean \
 && rm -rf /var/lib/apt/lists/*

COPY . .

CMD ["mpiexec", "-n", "2", ".venv/bin/python", "-m", "pimpm", "inputs/billet.yaml"]
