"""The layout of ``results.h5``: where each field goes, with which shape and
type (what XDMF and ParaView expect).

Layout of ``<directory>/results.h5``::

    /                      attrs: dim, lower, spacing, nodes (grid description)
    /steps/NNNNNN          attrs: step, time
    /steps/NNNNNN/particles/<field>   global arrays, rank-order concatenation
    /steps/NNNNNN/grid/<field>        node arrays in XDMF (z,) y, x order
    /polyvertex/<count>    (count, 1) int64 0..count-1: the particles' Polyvertex
                           connectivity, one per particle count, shared by the steps

Every dataset carries the attribute ``AttributeType`` (Scalar, Vector, Tensor,
Tensor6, Matrix, or GlobalId for the integer particle field ``id``), which is
also what the XDMF files declare.

Component conventions (what XDMF/ParaView expect):

* a field with per-item shape ``()`` is a Scalar, stored as ``(n,)``;
* per-item shape ``(dim,)`` or ``(3,)`` is a Vector, zero-padded to ``(n, 3)``
  (so 2-D positions get z = 0);
* ``(dim, dim)``, ``(3, 3)`` or ``(9,)`` is a Tensor, zero-padded to 3x3 and
  stored row-major as ``(n, 9)``; ``(6,)`` is stored as-is as a Tensor6;
* anything else is flattened to ``(n, k)`` and declared as a Matrix.

Grid fields are stored as ``(ny, nx) + comp`` in 2-D and ``(nz, ny, nx) + comp``
in 3-D (x varies fastest), with comp = ``()``, ``(3,)``, ``(9,)``, ``(6,)`` or ``(k,)``
by the same rules.
"""
import numpy as np

H5_NAME = "results.h5"
PARTICLES_XDMF = "particles.xdmf"
GRID_XDMF = "grid.xdmf"
POLYVERTEX = "polyvertex"  # /polyvertex/<count>: (count, 1) int64 0..count-1


def _step_name(step):
    return "%06d" % int(step)


def _xdmf_number_type(dtype):
    """(NumberType, Precision) of an XDMF DataItem for a numpy dtype."""
    dtype = np.dtype(dtype)
    if dtype.kind == "f":
        return "Float", str(dtype.itemsize)
    if dtype.kind == "i":
        return {1: "Char", 2: "Short"}.get(dtype.itemsize, "Int"), str(dtype.itemsize)
    if dtype.kind == "u":
        return {1: "UChar", 2: "UShort"}.get(dtype.itemsize, "UInt"), str(dtype.itemsize)
    raise ValueError("no XDMF number type for dtype %s" % dtype)


def _file_dtype(dtypes):
    """Common on-disk dtype for a field given the dtypes seen on the ranks."""
    dtypes = [np.dtype(d) for d in dtypes]
    for d in dtypes:
        if d.kind not in "biuf":
            raise ValueError("unsupported dtype %s (only bool, int, uint, float)" % d)
    dt = np.result_type(*dtypes)
    if dt.kind == "b":
        return np.dtype(np.uint8)
    if dt.kind == "f" and dt.itemsize < 4:
        return np.dtype(np.float32)
    if dt.kind == "f" and dt.itemsize > 8:
        return np.dtype(np.float64)
    if dt.kind == "u" and dt.itemsize > 4:
        return np.dtype(np.int64)  # XDMF readers have no 8-byte unsigned type
    return dt


def _classify(comp_shape, dim):
    """XDMF attribute type and stored per-item shape for a per-item shape."""
    comp_shape = tuple(int(c) for c in comp_shape)
    if comp_shape == ():
        return "Scalar", ()
    if len(comp_shape) == 1:
        k = comp_shape[0]
        if k in (dim, 3):
            return "Vector", (3,)
        if k == 9:
            return "Tensor", (9,)
        if k == 6:
            return "Tensor6", (6,)
        return "Matrix", (k,)
    if len(comp_shape) == 2 and comp_shape[0] == comp_shape[1] and comp_shape[0] in (dim, 3):
        return "Tensor", (9,)
    return "Matrix", (int(np.prod(comp_shape)),)


def _to_file_components(arr, nlead, kind, out_comp, dtype):
    """Pad/reshape the trailing (component) axes of ``arr`` to the stored layout."""
    lead = arr.shape[:nlead]
    comp = arr.shape[nlead:]
    if kind == "Vector" and comp[0] < 3:
        out = np.zeros(lead + (3,), dtype=dtype)
        out[..., :comp[0]] = arr
        return out
    if kind == "Tensor" and comp in ((2, 2),):
        out = np.zeros(lead + (3, 3), dtype=dtype)
        out[..., :2, :2] = arr
        return out.reshape(lead + (9,))
    return np.ascontiguousarray(arr, dtype=dtype).reshape(lead + tuple(out_comp))


def _attr_str(value):
    return value.decode() if isinstance(value, bytes) else str(value)


def _ordered(names):
    names = sorted(names)
    return (["position"] if "position" in names else []) + [n for n in names if n != "position"]
