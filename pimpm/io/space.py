"""Room on the disk before a parallel HDF5 write: a write that runs out of
space part-way leaves the ranks in different collective HDF5 calls (a
hang), so the writers first ask whether the file system has room for what
they are about to write, and all ranks stop together if it has not."""
import os

from ..errors import OutputFailed

#: room asked for beyond the data itself: HDF5's metadata, the XDMF files
MARGIN_BYTES = 1 << 20
MARGIN_FRACTION = 0.25


def free_bytes(directory):
    """Bytes an unprivileged writer may still use in ``directory``'s file system."""
    st = os.statvfs(directory)
    return st.f_bavail * st.f_frsize


def check_room(comm, directory, nbytes, what):
    """OutputFailed on every rank if ``directory`` has not room for
    ``nbytes`` (the global size of ``what``, known on every rank) plus a
    margin. Collective."""
    need = int(nbytes * (1.0 + MARGIN_FRACTION)) + MARGIN_BYTES
    free = None
    if comm.rank == 0:
        try:
            free = free_bytes(directory)
        except OSError:
            free = None                     # no answer: let the write find out
    if comm.size > 1:
        free = comm.bcast(free, root=0)
    if free is not None and free < need:
        raise OutputFailed(f"not enough room in {directory} for {what}: {free / 2**20:.1f} MiB free, "
                           f"about {need / 2**20:.1f} MiB needed (no space left on device)")
