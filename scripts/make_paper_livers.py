#!/usr/bin/python3
"""Derives the liver meshes of paper 000's experiments from SOFA's liver-smooth.obj.

The paper uses a liver of 170 x 140 x 160 mm with 1000 faces / 502 vertices (Tables I, II) and
versions with 2000..10000 faces (Table III). SOFA's liver-smooth.obj (LGPL-2.1+, 4384 faces) is
scaled so that its largest extent is 170 mm, Loop-subdivided when more faces are needed, and
reduced by quadric decimation to exactly the target face count (closed, genus 0, so V = F/2 + 2).
Run once by a developer (needs Debian's python3-vtk9); the outputs are committed in data/meshes/.
"""
import sys
import vtk

SRC = sys.argv[1] if len(sys.argv) > 1 else "../shared/data/meshes/sofa/liver-smooth.obj"
OUT = sys.argv[2] if len(sys.argv) > 2 else "data/meshes"


def read(path):
    r = vtk.vtkOBJReader()
    r.SetFileName(path)
    r.Update()
    clean = vtk.vtkCleanPolyData()
    clean.SetInputConnection(r.GetOutputPort())
    tri = vtk.vtkTriangleFilter()
    tri.SetInputConnection(clean.GetOutputPort())
    tri.Update()
    return tri.GetOutput()


def scaled(poly, size_mm):
    b = poly.GetBounds()
    ext = max(b[1] - b[0], b[3] - b[2], b[5] - b[4])
    c = [(b[0] + b[1]) / 2, (b[2] + b[3]) / 2, (b[4] + b[5]) / 2]
    t = vtk.vtkTransform()
    t.Scale(size_mm / ext, size_mm / ext, size_mm / ext)
    t.Translate(-c[0], -c[1], -c[2])
    f = vtk.vtkTransformPolyDataFilter()
    f.SetInputData(poly)
    f.SetTransform(t)
    f.Update()
    return f.GetOutput()


def decimate_to(poly, faces):
    lo, hi = 0.0, 0.999
    best = None
    for _ in range(60):
        mid = (lo + hi) / 2
        d = vtk.vtkQuadricDecimation()
        d.SetInputData(poly)
        d.SetTargetReduction(mid)
        d.VolumePreservationOn()
        d.Update()
        n = d.GetOutput().GetNumberOfPolys()
        if best is None or abs(n - faces) < abs(best.GetNumberOfPolys() - faces):
            best = vtk.vtkPolyData()
            best.DeepCopy(d.GetOutput())
        if n == faces:
            break
        if n > faces:
            lo = mid
        else:
            hi = mid
    return best


def write_obj(poly, path, faces):
    clean = vtk.vtkCleanPolyData()
    clean.SetInputData(poly)
    clean.Update()
    p = clean.GetOutput()
    with open(path, "w") as f:
        f.write("# Derived from SOFA share/mesh/liver-smooth.obj (LGPL-2.1-or-later), scaled to\n")
        f.write("# 170 mm, remeshed to %d faces by scripts/make_paper_livers.py. Units: mm.\n" % faces)
        for i in range(p.GetNumberOfPoints()):
            x = p.GetPoint(i)
            f.write("v %.6f %.6f %.6f\n" % x)
        for i in range(p.GetNumberOfCells()):
            ids = p.GetCell(i).GetPointIds()
            f.write("f %d %d %d\n" % (ids.GetId(0) + 1, ids.GetId(1) + 1, ids.GetId(2) + 1))
    print(path, p.GetNumberOfPoints(), "vertices", p.GetNumberOfCells(), "faces")


base = scaled(read(SRC), 170.0)
for faces in (1000, 2000, 4000, 6000, 8000, 10000):
    src = base
    if faces > base.GetNumberOfPolys():
        sub = vtk.vtkLoopSubdivisionFilter()
        sub.SetInputData(base)
        sub.SetNumberOfSubdivisions(1)
        sub.Update()
        src = sub.GetOutput()
    write_obj(decimate_to(src, faces), "%s/liver_%d.obj" % (OUT, faces), faces)
