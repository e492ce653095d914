"""A tube skinned to four bones with a "wave" animation: the picture of posed glTF in docs/formats.md.
`python3 bench/make_rigged_tube.py` writes tube.gltf here (numpy only); then, for example,
`meshvox render tube.gltf -r 64 --mode solid --pose 0.5 -o wave.png`."""
import base64
import json
import math
import struct

import numpy as np

SEGMENTS, RINGS, LENGTH, RADIUS, BONES = 24, 33, 4.0, 0.35, 4
ring_y = np.linspace(0.0, LENGTH, RINGS)
angles = np.linspace(0.0, 2 * math.pi, SEGMENTS, endpoint=False)
positions = np.array([(RADIUS * math.cos(a), y, RADIUS * math.sin(a)) for y in ring_y for a in angles], np.float32)
faces = []
for r in range(RINGS - 1):
    for s in range(SEGMENTS):
        a, b = r * SEGMENTS + s, r * SEGMENTS + (s + 1) % SEGMENTS
        faces += [(a, b + SEGMENTS, b), (a, a + SEGMENTS, b + SEGMENTS)]
for cap, flip in ((0, True), ((RINGS - 1) * SEGMENTS, False)):
    for s in range(1, SEGMENTS - 1):
        t = (cap, cap + s, cap + s + 1)
        faces.append(t[::-1] if flip else t)
faces = np.array(faces, np.uint16)
# Each vertex on the two bones nearest its height, blended linearly between their joints.
bone_len = LENGTH / BONES
joints, weights = [], []
for y in np.repeat(ring_y, SEGMENTS):
    f = min(y / bone_len - 0.5, BONES - 1.0)
    lo = max(0, min(int(math.floor(f)), BONES - 2))
    w = min(max(f - lo, 0.0), 1.0)
    joints.append((lo, lo + 1, 0, 0))
    weights.append((1 - w, w, 0, 0))
joints, weights = np.array(joints, np.uint16), np.array(weights, np.float32)
ibm = np.array([np.eye(4) for _ in range(BONES)], np.float32)
for k in range(BONES):
    ibm[k][1][3] = -k * bone_len
ibm = np.ascontiguousarray(np.transpose(ibm, (0, 2, 1)))  # column-major
times = np.array([0.0, 0.5, 1.0], np.float32)


def rot_z(deg):
    h = math.radians(deg) / 2
    return (0.0, 0.0, math.sin(h), math.cos(h))


rotations = [np.array([rot_z(0), rot_z(d), rot_z(-d)], np.float32) for d in (0, 25, 30, 35)]
chunks, views, accessors = [], [], []


def add(array, ty, component, extra=None):
    offset = sum(len(c) for c in chunks)
    data = array.tobytes()
    chunks.append(data + b"\0" * (-len(data) % 4))
    views.append({"buffer": 0, "byteOffset": offset, "byteLength": len(data)})
    accessors.append({"bufferView": len(views) - 1, "componentType": component, "count": len(array), "type": ty,
                      **(extra or {})})
    return len(accessors) - 1


pos = add(positions, "VEC3", 5126, {"min": positions.min(0).tolist(), "max": positions.max(0).tolist()})
jnt = add(joints, "VEC4", 5123)
wgt = add(weights, "VEC4", 5126)
idx = add(faces.reshape(-1), "SCALAR", 5123)
inv = add(ibm, "MAT4", 5126)
inp = add(times, "SCALAR", 5126, {"min": [0.0], "max": [1.0]})
outs = [add(r, "VEC4", 5126) for r in rotations]
data = b"".join(chunks)
nodes = [{"mesh": 0, "skin": 0}]
for k in range(BONES):
    node = {"name": f"bone{k}", "translation": [0.0, 0.0 if k == 0 else bone_len, 0.0]}
    if k + 1 < BONES:
        node["children"] = [k + 2]
    nodes.append(node)
gltf = {
    "asset": {"version": "2.0"}, "scene": 0, "scenes": [{"nodes": [0, 1]}], "nodes": nodes,
    "meshes": [{"primitives": [{"attributes": {"POSITION": pos, "JOINTS_0": jnt, "WEIGHTS_0": wgt}, "indices": idx}]}],
    "skins": [{"joints": list(range(1, BONES + 1)), "inverseBindMatrices": inv}],
    "animations": [{"name": "wave", "samplers": [{"input": inp, "output": o, "interpolation": "LINEAR"} for o in outs],
                    "channels": [{"sampler": k, "target": {"node": k + 1, "path": "rotation"}} for k in range(BONES)]}],
    "buffers": [{"byteLength": len(data), "uri": "data:application/octet-stream;base64," + base64.b64encode(data).decode()}],
    "bufferViews": views, "accessors": accessors,
}
with open("tube.gltf", "w") as f:
    json.dump(gltf, f)
