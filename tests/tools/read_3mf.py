"""Reads a .3mf with the 3MF Consortium's own library (lib3mf, from PyPI) for meshvox's tests, and prints one JSON
object: the model's unit, the reader's warnings, and per mesh object its name, counts, whether lib3mf finds it
manifold and consistently oriented, and (through trimesh, from the vertices and triangles lib3mf read) whether it
is watertight, its volume (positive when the triangles face outwards), its Euler characteristic and its bounds.

usage: read_3mf.py FILE.3mf
"""
import json
import sys

import lib3mf
import numpy as np
import trimesh

UNITS = {0: "micron", 1: "millimeter", 2: "centimeter", 3: "inch", 4: "foot", 5: "meter"}


def main():
    wrapper = lib3mf.get_wrapper()
    model = wrapper.CreateModel()
    reader = model.QueryReader("3mf")
    reader.ReadFromFile(sys.argv[1])
    objects = []
    meshes = model.GetMeshObjects()
    while meshes.MoveNext():
        o = meshes.GetCurrentMeshObject()
        vertices = np.array([list(v.Coordinates) for v in o.GetVertices()], dtype=np.float64)
        faces = np.array([list(t.Indices) for t in o.GetTriangleIndices()], dtype=np.int64)
        mesh = trimesh.Trimesh(vertices, faces, process=False)
        objects.append({
            "name": o.GetName(),
            "vertices": int(o.GetVertexCount()),
            "triangles": int(o.GetTriangleCount()),
            "manifold_and_oriented": bool(o.IsManifoldAndOriented()),
            "watertight": bool(mesh.is_watertight),
            "volume": float(mesh.volume),
            "euler": int(mesh.euler_number),
            "bounds": mesh.bounds.tolist(),
        })
    print(json.dumps({"unit": UNITS.get(int(model.GetUnit())), "warnings": int(reader.GetWarningCount()),
                      "objects": objects}))


main()
