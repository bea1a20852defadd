"""The one numba decorator every kernel uses: compiled once and cached on
disk, numpy's floating-point error model (x/0 gives inf or NaN as in numpy
instead of raising), no fast-math (results equal the numpy references to
round-off).

Where the cache lives. numba checks a cached kernel only against its own
source file, not against the kernels it calls from other files: after an
edit or an upgrade of one kernel module or material model, a kernel of
another module would keep running the old code. So the cache directory is
named after a hash of every kernel module's and material model's source:
``pimpm/kernels/__pycache__/numba-<hash>/``
(or under ``$NUMBA_CACHE_DIR``, or ``~/.cache/pimpm`` where the package
directory is read-only). A changed source gets a fresh cache.
"""
import hashlib
import os

import numba

HERE = os.path.dirname(os.path.abspath(__file__))


#: the packages whose modules hold compiled code: the kernels and the material models
COMPILED_PACKAGES = (HERE, os.path.join(os.path.dirname(HERE), "materials"))


def source_hash():
    """Hash of the compiled modules' sources (names and contents)."""
    digest = hashlib.sha256()
    for package in COMPILED_PACKAGES:
        for name in sorted(os.listdir(package)):
            if name.endswith(".py"):
                digest.update(name.encode())
                with open(os.path.join(package, name), "rb") as f:
                    digest.update(f.read())
    return digest.hexdigest()[:16]


def cache_directory():
    """A writable directory for this version of the kernels' compiled code."""
    name = "numba-" + source_hash()
    bases = [os.environ.get("NUMBA_CACHE_DIR"), os.path.join(HERE, "__pycache__"),
             os.path.join(os.path.expanduser("~"), ".cache", "pimpm")]
    for base in bases:
        if not base:
            continue
        path = os.path.join(base, name)
        try:
            os.makedirs(path, exist_ok=True)
        except OSError:
            continue
        if os.access(path, os.W_OK):
            return path
    return None        # no writable place: numba compiles in memory every run


CACHE_DIRECTORY = cache_directory()
if CACHE_DIRECTORY is not None:
    # read when each cached kernel below is decorated (before any of them is)
    numba.config.CACHE_DIR = CACHE_DIRECTORY

#: the compiler options of every kernel (also those of numba.extending.overload's)
JIT_OPTIONS = {"error_model": "numpy", "nogil": True}
jit = numba.njit(cache=CACHE_DIRECTORY is not None, **JIT_OPTIONS)
#: for a few-line helper called in an inner loop: inlined where numba compiles
#: the caller (a call with array arguments costs tens of ns per particle)
jit_inline = numba.njit(cache=CACHE_DIRECTORY is not None, inline="always", **JIT_OPTIONS)
