"""The output directory: never overwrite results unless asked, never write
through a link."""
import os

from ..errors import UsageError
from .layout import GRID_XDMF, H5_NAME, PARTICLES_XDMF

HISTORY_CSV = "history.csv"
CHECKPOINT_H5 = "checkpoint.h5"
#: the SHA-256 digests a checkpoint.h5 may have (pimpm.io.checkpoint)
CHECKPOINT_SUM = "checkpoint.sha256"
OUTPUT_FILES = (H5_NAME, PARTICLES_XDMF, GRID_XDMF, HISTORY_CSV, CHECKPOINT_H5, CHECKPOINT_SUM)
#: every name pimpm writes in the output directory (results and their temporaries)
ALL_NAMES = OUTPUT_FILES + tuple(f + ".tmp" for f in OUTPUT_FILES)


def write_problem(directory):
    """Why pimpm cannot create files in the existing ``directory`` (a
    phrase), or None.
    Tried with a file (permissions do not bind root, a read-only file system
    or an ACL may bind anyone): os.access alone would pass what fails later."""
    probe = os.path.join(directory, f".pimpm-write-test-{os.getpid()}")
    try:
        os.close(os.open(probe, os.O_WRONLY | os.O_CREAT | os.O_EXCL, 0o600))
        os.remove(probe)
    except OSError as err:
        return f"cannot create files in it ({err.strerror}): expected a directory this user may write"
    return None


def prepare_output_directory(comm, directory, overwrite):
    """Refuse to overwrite results unless asked; create the directory.
    Collective; raises UsageError on every rank."""
    problem = None
    if comm.rank == 0:
        existing = [f for f in OUTPUT_FILES if os.path.lexists(os.path.join(directory, f))]
        links = [f for f in ALL_NAMES if os.path.islink(os.path.join(directory, f))]
        # what --overwrite could not remove: refused before anything is removed (issue 32:
        # a directory named results.h5 came after the other files were gone)
        odd = [f for f in ALL_NAMES if os.path.lexists(os.path.join(directory, f))
               and not os.path.islink(os.path.join(directory, f)) and not os.path.isfile(os.path.join(directory, f))]
        if os.path.exists(directory) and not os.path.isdir(directory):
            problem = f"output.directory = {directory!r}: exists and is not a directory"
        elif odd:
            problem = (f"output.directory = {directory!r}: {os.path.join(directory, odd[0])!r} is not a "
                       f"file: expected pimpm's output names to be files it may replace (remove it)")
        elif links:
            problem = (f"output.directory = {directory!r}: {os.path.join(directory, links[0])!r} is a "
                       f"symbolic link: expected pimpm's output files not to be links (pimpm never "
                       f"writes through one; remove it)")
        elif existing and not overwrite:
            problem = (f"output.directory = {directory!r} already holds results "
                       f"({', '.join(existing)}): expected a new directory "
                       f"(or pass --overwrite to replace them)")
    if comm.rank == 0 and problem is None and os.path.isdir(directory):
        problem = write_problem(directory)      # before --overwrite removes anything
        problem = problem and f"output.directory = {directory!r}: {problem}"
    if comm.rank == 0 and problem is None:
        try:
            os.makedirs(directory, exist_ok=True)
            for f in ALL_NAMES:
                if os.path.lexists(os.path.join(directory, f)):
                    os.remove(os.path.join(directory, f))
        except OSError as err:
            problem = (f"output.directory = {directory!r}: cannot be created or cleared "
                       f"({err.strerror}): expected a writable directory path")
    problem = comm.bcast(problem)
    if problem:
        raise UsageError(problem)
