import json, struct, base64, os, random, sys
root = sys.argv[1]
bad = os.path.join(root, "bad"); odd = os.path.join(root, "odd")
os.makedirs(bad, exist_ok=True); os.makedirs(odd, exist_ok=True)
def w(d, name, data):
    if isinstance(data, str): data = data.encode()
    open(os.path.join(d, name), "wb").write(data)

tri = "v 0.1 0.2 0.3\nv 1.7 0.2 0.3\nv 0.1 1.9 0.3\n"
# --- bad OBJ
w(bad, "empty.obj", b"")
w(bad, "comments-only.obj", "# exported by nothing\n# v 1 2 3\n\n")
rnd = random.Random(10)
w(bad, "random-bytes.obj", bytes(rnd.randrange(256) for _ in range(512)))
w(bad, "nan-vertex.obj", "v 0 0 0\nv nan 0 0\nv 0 1 0\nf 1 2 3\n")
w(bad, "inf-vertex.obj", "v 0 0 0\nv inf 0 0\nv 0 1 0\nf 1 2 3\n")
w(bad, "overflow-vertex.obj", "v 0 0 0\nv 1e39 0 0\nv 0 1 0\nf 1 2 3\n")
w(bad, "index-out-of-range.obj", tri + "f 1 2 7\n")
w(bad, "index-zero.obj", tri + "f 0 1 2\n")
w(bad, "negative-index-before-start.obj", tri + "f -5 -1 -2\n")
w(bad, "two-vertex-face.obj", tri + "f 1 2 3\nf 1 2\n")
w(bad, "one-vertex-face.obj", tri + "f 1\n")
w(bad, "non-numeric-vertex.obj", "v 0 0 0\nv 1 abc 0\nv 0 1 0\nf 1 2 3\n")
w(bad, "non-numeric-index.obj", tri + "f 1 x 3\n")
w(bad, "malformed-number.obj", "v 0 0 0\nv 1 1.2.3 0\nv 0 1 0\nf 1 2 3\n")
w(bad, "missing-coordinate.obj", "v 0 0 0\nv 1 0\nv 0 1 0\nf 1 2 3\n")
w(bad, "huge-index.obj", tri + "f 1 2 99999999999999999999\n")
w(bad, "lines-only.obj", tri + "l 1 2\nl 2 3\n")
w(bad, "nul-bytes.obj", tri.encode() + b"f 1 2\x00 3\n")

# --- glTF helpers
def blob_tri(n_idx=3):
    data = b"".join(struct.pack("<f", v) for v in [0.1,0.2,0.3, 1.7,0.2,0.3, 0.1,1.9,0.3])
    data += b"".join(struct.pack("<H", i) for i in [0,1,2]) + b"\x00\x00"
    return data
def doc(data, views=None, accessors=None, extra=None, uri=True, mesh_extra=None):
    d = {"asset": {"version": "2.0"}, "scene": 0, "scenes": [{"nodes": [0]}], "nodes": [{"mesh": 0}],
         "meshes": [{"primitives": [{"attributes": {"POSITION": 0}, "indices": 1}]}],
         "buffers": [{"byteLength": len(data)}],
         "bufferViews": views or [{"buffer": 0, "byteOffset": 0, "byteLength": 36}, {"buffer": 0, "byteOffset": 36, "byteLength": 6}],
         "accessors": accessors or [
             {"bufferView": 0, "componentType": 5126, "count": 3, "type": "VEC3", "min": [0.1,0.2,0.3], "max": [1.7,1.9,0.3]},
             {"bufferView": 1, "componentType": 5123, "count": 3, "type": "SCALAR"}]}
    if uri: d["buffers"][0]["uri"] = "data:application/octet-stream;base64," + base64.b64encode(data).decode()
    if extra: extra(d)
    return d
def gltf(name, d, where=bad): w(where, name, json.dumps(d, indent=1))
def glb(d, binchunk, version=2, magic=b"glTF"):
    js = json.dumps(d).encode(); js += b" " * (-len(js) % 4)
    out = struct.pack("<II", len(js), 0x4E4F534A) + js
    if binchunk is not None:
        b = binchunk + b"\x00" * (-len(binchunk) % 4)
        out += struct.pack("<II", len(b), 0x004E4942) + b
    return magic + struct.pack("<II", version, 12 + len(out)) + out

data = blob_tri()
w(bad, "empty.gltf", b"")
w(bad, "not-json.gltf", "{ this is not json")
w(bad, "json-array.gltf", "[1, 2, 3]")
w(bad, "no-asset.gltf", "{}")
gltf("version-1.gltf", doc(data, extra=lambda d: d["asset"].update(version="1.0")))
# The issue's file: 99 indices claimed in a short index view.
gltf("index-count-past-view.gltf", doc(data, accessors=[
    {"bufferView": 0, "componentType": 5126, "count": 3, "type": "VEC3", "min": [0.1,0.2,0.3], "max": [1.7,1.9,0.3]},
    {"bufferView": 1, "componentType": 5123, "count": 99, "type": "SCALAR"}]))
gltf("view-past-buffer.gltf", doc(data, views=[{"buffer": 0, "byteOffset": 0, "byteLength": 36}, {"buffer": 0, "byteOffset": 36, "byteLength": 600}]))
gltf("stride-too-small.gltf", doc(data, views=[{"buffer": 0, "byteOffset": 0, "byteLength": 36, "byteStride": 4}, {"buffer": 0, "byteOffset": 36, "byteLength": 6}]))
def missing_bin(d):
    d["buffers"][0]["uri"] = "does-not-exist.bin"
gltf("missing-bin.gltf", doc(data, extra=missing_bin))
def bad_b64(d):
    d["buffers"][0]["uri"] = "data:application/octet-stream;base64,@@@not base64@@@"
gltf("bad-base64.gltf", doc(data, extra=bad_b64))
def short_buffer(d):
    d["buffers"][0]["byteLength"] = 4000
gltf("buffer-shorter-than-declared.gltf", doc(data, extra=short_buffer))
badidx = data[:36] + struct.pack("<HHH", 0, 1, 9) + b"\x00\x00"
gltf("index-out-of-range.gltf", doc(badidx))
nanpos = struct.pack("<9f", 0.1, 0.2, 0.3, float("nan"), 0.2, 0.3, 0.1, 1.9, 0.3) + data[36:]
gltf("nan-position.gltf", doc(nanpos))
infpos = struct.pack("<9f", 0.1, 0.2, 0.3, float("inf"), 0.2, 0.3, 0.1, 1.9, 0.3) + data[36:]
gltf("inf-position.gltf", doc(infpos))
gltf("position-wrong-type.gltf", doc(data, accessors=[
    {"bufferView": 0, "componentType": 5126, "count": 9, "type": "SCALAR"},
    {"bufferView": 1, "componentType": 5123, "count": 3, "type": "SCALAR"}]))
gltf("position-wrong-component.gltf", doc(data, accessors=[
    {"bufferView": 0, "componentType": 5121, "count": 3, "type": "VEC3"},
    {"bufferView": 1, "componentType": 5123, "count": 3, "type": "SCALAR"}]))
gltf("float-indices.gltf", doc(data, accessors=[
    {"bufferView": 0, "componentType": 5126, "count": 3, "type": "VEC3", "min": [0.1,0.2,0.3], "max": [1.7,1.9,0.3]},
    {"bufferView": 1, "componentType": 5126, "count": 1, "type": "SCALAR"}]))
gltf("node-cycle.gltf", doc(data, extra=lambda d: d.update(nodes=[{"mesh": 0, "children": [1]}, {"children": [0]}])))
# Each node lists the next one twice: not a tree, and a walk that follows it visits 2^40 nodes.
gltf("node-graph-not-tree.gltf", doc(data, extra=lambda d: d.update(nodes=[{"children": [i + 1, i + 1]} for i in range(40)] + [{"mesh": 0}])))
gltf("mesh-out-of-range.gltf", doc(data, extra=lambda d: d.update(nodes=[{"mesh": 5}])))
gltf("accessor-out-of-range.gltf", doc(data, extra=lambda d: d["meshes"][0]["primitives"][0].update(indices=7)))
gltf("no-position.gltf", doc(data, extra=lambda d: d["meshes"][0]["primitives"][0].update(attributes={"NORMAL": 0})))
gltf("required-extension.gltf", doc(data, extra=lambda d: d.update(extensionsRequired=["MSFT_lod"], extensionsUsed=["MSFT_lod"])))
# --- bad GLB
d_glb = doc(data, uri=False)
good_glb = glb(d_glb, data)
w(bad, "wrong-magic.glb", b"glTX" + good_glb[4:])
w(bad, "truncated-header.glb", good_glb[:10])
w(bad, "truncated-body.glb", good_glb[:len(good_glb) // 2])
w(bad, "length-too-large.glb", good_glb[:8] + struct.pack("<I", len(good_glb) + 100) + good_glb[12:])
w(bad, "version-1.glb", glb(d_glb, data, version=1))
jsbad = b"{ not json }    "
w(bad, "json-chunk-not-json.glb", b"glTF" + struct.pack("<II", 2, 12 + 8 + len(jsbad)) + struct.pack("<II", len(jsbad), 0x4E4F534A) + jsbad)
chunk = bytearray(good_glb); struct.pack_into("<I", chunk, 12, 0x7fffffff)
w(bad, "chunk-length-past-end.glb", bytes(chunk))
w(bad, "bin-chunk-missing.glb", glb(d_glb, None))
w(bad, "random-bytes.glb", b"glTF" + bytes(rnd.randrange(256) for _ in range(300)))
w(bad, "mesh.stl", "solid x\nendsolid x\n")

# --- bad STL and PLY
stl_tri = struct.pack("<12f", 0, 0, 1, 0.1, 0.2, 0.3, 1.7, 0.2, 0.3, 0.1, 1.9, 0.3) + b"\x00\x00"
w(bad, "binary-count-too-large.stl", b"\x00" * 80 + struct.pack("<I", 1000) + stl_tri)
w(bad, "binary-truncated.stl", (b"\x00" * 80 + struct.pack("<I", 2) + stl_tri * 2)[:-7])
w(bad, "ascii-two-vertex-facet.stl", "solid t\nfacet normal 0 0 1\nouter loop\nvertex 0 0 0\nvertex 1 0 0\nendloop\nendfacet\nendsolid t\n")
w(bad, "ascii-bad-number.stl", "solid t\nfacet normal 0 0 1\nouter loop\nvertex 0 0 0\nvertex 1 zero 0\nvertex 0 1 0\nendloop\nendfacet\nendsolid t\n")
w(bad, "ascii-cut-short.stl", "solid t\nfacet normal 0 0 1\nouter loop\nvertex 0 0 0\nvertex 1 0 0\n")
ply_head = "ply\nformat ascii 1.0\nelement vertex 3\nproperty float x\nproperty float y\nproperty float z\n"
w(bad, "face-index-out-of-range.ply", ply_head + "element face 1\nproperty list uchar int vertex_indices\nend_header\n0 0 0\n1 0 0\n0 1 0\n3 0 1 5\n")
w(odd, "points-only.ply", ply_head + "end_header\n0 0 0\n1 0 0\n0 1 0\n")
w(bad, "fewer-vertices-than-declared.ply", ply_head.replace("vertex 3", "vertex 5") + "element face 1\nproperty list uchar int vertex_indices\nend_header\n0 0 0\n1 0 0\n0 1 0\n3 0 1 2\n")
w(bad, "binary-truncated.ply", "ply\nformat binary_little_endian 1.0\nelement vertex 3\nproperty float x\nproperty float y\nproperty float z\nelement face 1\nproperty list uchar int vertex_indices\nend_header\n".encode() + struct.pack("<9f", 0, 0, 0, 1, 0, 0, 0, 1, 0) + b"\x03\x00\x00")
w(bad, "not-a-ply-header.ply", "ply\nformat ascii 1.0\nelement vertex three\nend_header\n")

# --- odd but valid
w(odd, "single-triangle.obj", tri + "f 1 2 3\n")
w(odd, "all-degenerate.obj", "v 0.1 0.2 0.3\nv 0.6 0.2 0.3\nv 1.35 0.2 0.3\nv 2.05 0.2 0.3\nf 1 2 3\nf 2 3 4\nf 1 1 1\nf 4 4 2\n")
w(odd, "far-from-origin.obj", "v 100000.1 -250000.3 7000.7\nv 100001.9 -250000.3 7000.7\nv 100000.1 -249998.6 7001.25\nf 1 2 3\n")
w(odd, "crlf-no-final-newline.obj", (tri + "f 1 2 3").replace("\n", "\r\n"))
w(odd, "polygons-negative-indices.obj", "o a\nv 0 0 0\nv 1.5 0 0\nv 1.5 1.5 0\nv 0 1.5 0\nv 0.7 2.2 0.4\nvt 0 0\nvn 0 0 1\nf -5/1/1 -4/1/1 -3/1/1 -2/1/1 -1/1/1\n")
w(odd, "unknown-statements.obj", "mtllib missing.mtl\nusemtl x\ns 1\ng grp\n" + tri + "vp 0.5\nf 1 2 3\n")
gltf("index-count-not-multiple-of-3.gltf", doc(data + struct.pack("<HH", 2, 1), views=[{"buffer": 0, "byteOffset": 0, "byteLength": 36}, {"buffer": 0, "byteOffset": 36, "byteLength": 10}], accessors=[
    {"bufferView": 0, "componentType": 5126, "count": 3, "type": "VEC3", "min": [0.1,0.2,0.3], "max": [1.7,1.9,0.3]},
    {"bufferView": 1, "componentType": 5123, "count": 5, "type": "SCALAR"}]), where=odd)
# A zero-length BIN chunk for buffer 0 (unused) while the mesh reads buffer 1 from a data URI.
def two_buffers(d):
    d["buffers"] = [{"byteLength": 0}, {"byteLength": len(data), "uri": "data:application/octet-stream;base64," + base64.b64encode(data).decode()}]
    for v in d["bufferViews"]: v["buffer"] = 1
w(odd, "zero-length-bin-chunk.glb", glb(doc(data, uri=False, extra=two_buffers), b""))
w(odd, "single-triangle.glb", good_glb)
# Indices [0, 1, 1] whose sparse substitution sets the third to 2: the triangle only exists with it applied.
sparse_data = blob_tri()[:36] + struct.pack("<HHHHH", 0, 1, 1, 2, 2) + b"\x00\x00"
gltf("sparse-indices.gltf", doc(sparse_data, views=[{"buffer": 0, "byteOffset": 0, "byteLength": 36}, {"buffer": 0, "byteOffset": 36, "byteLength": 6},
    {"buffer": 0, "byteOffset": 42, "byteLength": 2}, {"buffer": 0, "byteOffset": 44, "byteLength": 2}], accessors=[
    {"bufferView": 0, "componentType": 5126, "count": 3, "type": "VEC3", "min": [0.1,0.2,0.3], "max": [1.7,1.9,0.3]},
    {"bufferView": 1, "componentType": 5123, "count": 3, "type": "SCALAR",
     "sparse": {"count": 1, "indices": {"bufferView": 2, "componentType": 5123}, "values": {"bufferView": 3}}}]), where=odd)
# KHR_mesh_quantization: normalized int16 positions (the triangle on a 32767 lattice) dequantized by the node's
# scale and translation, as gltfpack writes them.
quantized = struct.pack("<9h", 0, 0, 0, 32767, 0, 0, 0, 32767, 0) + b"\x00\x00" + struct.pack("<HHH", 0, 1, 2) + b"\x00\x00"
gltf("quantized-positions.gltf", doc(quantized, views=[{"buffer": 0, "byteOffset": 0, "byteLength": 18}, {"buffer": 0, "byteOffset": 20, "byteLength": 6}], accessors=[
    {"bufferView": 0, "componentType": 5122, "normalized": True, "count": 3, "type": "VEC3", "min": [0, 0, 0], "max": [1, 1, 0]},
    {"bufferView": 1, "componentType": 5123, "count": 3, "type": "SCALAR"}],
    extra=lambda d: d.update(extensionsUsed=["KHR_mesh_quantization"], extensionsRequired=["KHR_mesh_quantization"],
                             nodes=[{"mesh": 0, "scale": [1.6, 1.7, 1.0], "translation": [0.1, 0.2, 0.3]}])), where=odd)
w(odd, "single-triangle.stl", b"solid-looking header of a binary STL".ljust(80, b" ") + struct.pack("<I", 1) + stl_tri)
w(odd, "quad-with-colours.ply", ply_head.replace("vertex 3", "vertex 4") + "property uchar red\nproperty uchar green\nproperty uchar blue\nelement face 1\nproperty list uchar int vertex_indices\nend_header\n0 0 0 255 0 0\n1.5 0 0 0 255 0\n1.5 1.5 0 0 0 255\n0 1.5 0.2 255 255 255\n4 0 1 2 3\n")
