#!/usr/bin/env python3
"""Writes tests/data/meshes/tet2_vtk_*.vtu with VTK's own XML writer, in the layouts VTK writes:
appended raw zlib (VTK's default), appended raw uncompressed with UInt32 headers, appended
base64 zlib, inline base64 zlib, many small compressed blocks, big-endian. The mesh is the
reader fixtures' five points and three cells (two tetrahedra and a triangle), with a point
array and an integer cell array `region` (1, 2, 3). MeshIoFixtures.VtkWrittenVtuInEveryLayout reads
them back. Run once, with Debian's python3-vtk9; the files are committed, so CI needs no VTK.

    python3 scripts/meshes/write_vtu_variants.py [OUT_DIR]   (default tests/data/meshes)
"""
import os
import sys

import vtk

POINTS = [(0, 0, 0), (1, 0, 0), (0, 1, 0), (0, 0, 1), (1.5, 1.25, -2.0)]
CELLS = [(vtk.VTK_TETRA, (0, 1, 2, 3)), (vtk.VTK_TRIANGLE, (0, 1, 2)), (vtk.VTK_TETRA, (1, 2, 3, 4))]


def grid():
    pts = vtk.vtkPoints()
    pts.SetDataTypeToDouble()
    for p in POINTS:
        pts.InsertNextPoint(*p)
    g = vtk.vtkUnstructuredGrid()
    g.SetPoints(pts)
    for kind, ids in CELLS:
        idl = vtk.vtkIdList()
        for i in ids:
            idl.InsertNextId(i)
        g.InsertNextCell(kind, idl)
    t = vtk.vtkFloatArray()
    t.SetName("t")
    for v in (1, 2, 3, 4, 5):
        t.InsertNextValue(v)
    g.GetPointData().AddArray(t)
    r = vtk.vtkIntArray()
    r.SetName("region")
    for v in (1, 2, 3):
        r.InsertNextValue(v)
    g.GetCellData().AddArray(r)
    return g


def write(path, mode="appended", encode=False, compress=True, header64=True, block=None, big=False):
    w = vtk.vtkXMLUnstructuredGridWriter()
    w.SetFileName(path)
    w.SetInputData(grid())
    if mode == "appended":
        w.SetDataModeToAppended()
        w.SetEncodeAppendedData(1 if encode else 0)
    else:
        w.SetDataModeToBinary()
    if compress:
        w.SetCompressorTypeToZLib()
    else:
        w.SetCompressorTypeToNone()
    if header64:
        w.SetHeaderTypeToUInt64()
    else:
        w.SetHeaderTypeToUInt32()
    if block:
        w.SetBlockSize(block)
    if big:
        w.SetByteOrderToBigEndian()
    else:
        w.SetByteOrderToLittleEndian()
    if not w.Write():
        sys.exit(f"VTK failed to write {path}")


def main():
    out = sys.argv[1] if len(sys.argv) > 1 else os.path.join(os.path.dirname(__file__), "..", "..", "tests", "data", "meshes")
    variants = {
        "tet2_vtk_appended_raw_zlib.vtu": {},  # VTK's defaults: appended, raw, zlib, UInt64
        "tet2_vtk_appended_raw_u32.vtu": dict(compress=False, header64=False),
        "tet2_vtk_appended_base64_zlib.vtu": dict(encode=True),
        "tet2_vtk_inline_zlib.vtu": dict(mode="binary"),
        "tet2_vtk_appended_zlib_blocks.vtu": dict(block=16, header64=False),
        "tet2_vtk_appended_raw_zlib_big_endian.vtu": dict(big=True),
    }
    for name, kw in variants.items():
        write(os.path.join(out, name), **kw)
        print("wrote", name, f"(VTK {vtk.vtkVersion.GetVTKVersion()})")


if __name__ == "__main__":
    main()
