"""The XDMF files that describe results.h5 to ParaView (``particles.xdmf``,
``grid.xdmf``; XDMF 3.0, relative paths to ``results.h5``). Rank 0 rewrites
them after every step through a temporary file and ``os.replace``.

* ``particles.xdmf``: Temporal collection of Polyvertex grids (connectivity
  ``/polyvertex/<count>``), geometry XYZ from ``particles/position``, one Node
  attribute per field, ``id`` as a GlobalId. Steps with no particles at
  all are left out (zero-sized DataItems upset the readers).
* ``grid.xdmf``: Temporal collection of ``3DCoRectMesh`` grids (Dimensions, Origin
  and Spacing in z y x order, ORIGIN_DXDYDZ). A 2-D grid is described as one node
  layer (nz = 1, origin z = 0): ParaView 5.11 (Xdmf3ReaderS/T and the legacy
  XDMFReader) places a ``2DCoRectMesh`` in the x = 0 plane, away from the particles,
  and the legacy reader fails on its vector attributes. The HDF5 arrays keep their
  ``(ny, nx, ...)`` shape; their DataItems declare ``(1, ny, nx, ...)``.
"""
import os
import xml.etree.ElementTree as ET

import numpy as np

from .safe_files import atomic_write_text
from .layout import GRID_XDMF, H5_NAME, PARTICLES_XDMF, POLYVERTEX, _xdmf_number_type


def write_xdmf(directory, records, dim, nodes, lower, spacing):
    """Rewrite particles.xdmf and grid.xdmf for the step records (rank 0)."""
    records = [records[s] for s in sorted(records)]
    prec = [r for r in records if r["particles"] is not None and r["particles"]["count"] > 0]
    grec = [r for r in records if r["grid"] is not None]
    if prec:
        _atomic_write(os.path.join(directory, PARTICLES_XDMF), particles_xdmf(prec))
    if grec:
        _atomic_write(os.path.join(directory, GRID_XDMF),
                      grid_xdmf(grec, dim, nodes, lower, spacing))

def _attribute(parent, name, kind, shape, dtype, h5path):
    att = ET.SubElement(parent, "Attribute", Name=name, AttributeType=kind, Center="Node")
    _data_item(att, shape, dtype, h5path)

def particles_xdmf(records):
    """Temporal collection of Polyvertex grids, one per step with particles."""
    root, coll = _xdmf_root("particles")
    for rec in records:
        n = rec["particles"]["count"]
        grid = ET.SubElement(coll, "Grid", Name="particles_" + rec["name"], GridType="Uniform")
        ET.SubElement(grid, "Time", Value=repr(float(rec["time"])))
        topology = ET.SubElement(grid, "Topology", TopologyType="Polyvertex",
                                 NumberOfElements=str(n), NodesPerElement="1")
        # with its connectivity: without it the Xdmf3 readers make no cells
        # and meshio's TimeSeriesReader refuses the topology
        _data_item(topology, (n, 1), "int64", "%s:/%s/%d" % (H5_NAME, POLYVERTEX, n))
        base = "%s:/steps/%s/particles/" % (H5_NAME, rec["name"])
        fields = {f[0]: f for f in rec["particles"]["fields"]}
        geo = ET.SubElement(grid, "Geometry", GeometryType="XYZ")
        pos = fields["position"]
        _data_item(geo, pos[2], pos[3], base + "position")
        for name, kind, shape, dtype in rec["particles"]["fields"]:
            _attribute(grid, name, kind, shape, dtype, base + name)
    return root

def grid_xdmf(records, dim, nodes, lower, spacing):
    """Temporal collection of 3DCoRectMesh grids, one per step."""
    # 2-D grids are described as 3DCoRectMesh with one node layer (nz = 1,
    # z = 0): ParaView 5.11 puts a 2DCoRectMesh in the x = 0 plane (its two
    # Dimensions become z and y), away from the particles at z = 0, and its
    # legacy XDMF reader then fails on vector attributes. The HDF5 arrays keep
    # their (ny, nx, ...) shape; the DataItems declare (1, ny, nx, ...), which
    # holds the same values in the same order.
    root, coll = _xdmf_root("grid")
    layer = ()
    if dim == 2:
        nodes = np.append(nodes, 1)
        lower = np.append(lower, 0.0)
        spacing = np.append(spacing, 1.0)
        layer = (1,)
    dims = " ".join(str(int(n)) for n in nodes[::-1])
    origin = " ".join(repr(float(x)) for x in lower[::-1])
    step = " ".join(repr(float(x)) for x in spacing[::-1])
    for rec in records:
        grid = ET.SubElement(coll, "Grid", Name="grid_" + rec["name"], GridType="Uniform")
        ET.SubElement(grid, "Time", Value=repr(float(rec["time"])))
        ET.SubElement(grid, "Topology", TopologyType="3DCoRectMesh", Dimensions=dims)
        geo = ET.SubElement(grid, "Geometry", GeometryType="ORIGIN_DXDYDZ")
        for label, text in (("Origin", origin), ("Spacing", step)):
            item = ET.SubElement(geo, "DataItem", Name=label, Dimensions="3",
                                 NumberType="Float", Precision="8", Format="XML")
            item.text = text
        base = "%s:/steps/%s/grid/" % (H5_NAME, rec["name"])
        for name, kind, shape, dtype in rec["grid"]["fields"]:
            _attribute(grid, name, kind, layer + tuple(shape), dtype, base + name)
    return root


def _xdmf_root(name):
    root = ET.Element("Xdmf", Version="3.0")
    root.set("xmlns:xi", "http://www.w3.org/2001/XInclude")
    domain = ET.SubElement(root, "Domain")
    coll = ET.SubElement(domain, "Grid", Name=name, GridType="Collection",
                         CollectionType="Temporal")
    return root, coll


def _data_item(parent, shape, dtype, h5path):
    ntype, precision = _xdmf_number_type(dtype)
    item = ET.SubElement(parent, "DataItem", Dimensions=" ".join(str(int(s)) for s in shape),
                         NumberType=ntype, Precision=precision, Format="HDF")
    item.text = h5path
    return item


def _atomic_write(path, root):
    """Write the XML tree to ``path`` via a temporary file and os.replace."""
    if hasattr(ET, "indent"):
        ET.indent(root, space="  ")
    body = ET.tostring(root, encoding="unicode")
    text = '<?xml version="1.0" ?>\n<!DOCTYPE Xdmf SYSTEM "Xdmf.dtd" []>\n' + body + "\n"
    atomic_write_text(path, text)
