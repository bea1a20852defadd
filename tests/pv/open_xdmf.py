"""Run by pvbatch: open an XDMF file with ParaView's three readers and print
one JSON line (points, cells, steps, arrays, global ids, threshold on body 0)."""
import json
import sys

from paraview import servermanager
from paraview.simple import Delete, Threshold, XDMFReader, Xdmf3ReaderS, Xdmf3ReaderT


def dataset(proxy):
    data = servermanager.Fetch(proxy)
    if data.IsA("vtkMultiBlockDataSet") or data.IsA("vtkCompositeDataSet"):
        it = data.NewIterator()
        it.InitTraversal()
        data = it.GetCurrentDataObject()
    return data


path = sys.argv[1]
by = sys.argv[2] if len(sys.argv) > 2 else None  # a point field to threshold at 0
out = {}
for name, make in (("Xdmf3ReaderS", lambda: Xdmf3ReaderS(FileName=[path])),
                   ("Xdmf3ReaderT", lambda: Xdmf3ReaderT(FileName=[path])),
                   ("XDMFReader", lambda: XDMFReader(FileNames=[path]))):
    reader = make()
    times = list(reader.TimestepValues or [])
    last = times[-1] if times else 0.0
    reader.UpdatePipeline(last)
    info = reader.GetDataInformation()
    data = dataset(reader)
    gids = data.GetPointData().GetGlobalIds()
    kept = None
    if by is not None:
        threshold = Threshold(Input=reader, Scalars=["POINTS", by])
        threshold.LowerThreshold = 0
        threshold.UpperThreshold = 0
        threshold.UpdatePipeline(last)
        kept = threshold.GetDataInformation().GetNumberOfCells()
        Delete(threshold)
    out[name] = dict(points=info.GetNumberOfPoints(), cells=info.GetNumberOfCells(),
                     steps=len(times), last_time=last,
                     arrays=sorted(reader.PointData.keys()),
                     global_ids=gids.GetName() if gids is not None else None,
                     threshold_cells=kept)
    Delete(reader)
print("RESULT " + json.dumps(out))
