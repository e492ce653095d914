"""A picket fence on two crossed quads, textured with alpha 0 between the planks: the picture of alpha cut-outs in
docs/formats.md. `python3 bench/make_fence.py MASK|OPAQUE` writes fence-mask.gltf or fence-opaque.gltf here (numpy, Pillow)."""
import base64, json, io, struct, sys
import numpy as np
from PIL import Image
mode = sys.argv[1]
# A 64x64 picket fence: planks 10 texels wide with 6-texel gaps, pointed tops, two rails; alpha 0 elsewhere.
w = 64
img = np.zeros((w, w, 4), np.uint8)
for x in range(w):
    plank = (x % 16) < 10
    centre = (x // 16) * 16 + 4.5
    for y in range(w):
        top = 6 + abs(x - centre) * 1.2
        rail = 22 <= y <= 27 or 46 <= y <= 51
        if (plank and y >= top and y < 62) or (rail and y < 62):
            shade = 200 - 25 * ((x % 16) in (0, 9)) - 30 * rail
            img[y, x] = (shade, int(shade * 0.72), int(shade * 0.45), 255)
buf = io.BytesIO(); Image.fromarray(img).save(buf, 'PNG')
png = buf.getvalue()
# Two crossed quads (an X seen from above), 2 units wide and tall.
quads = [[(-1, 0, -1), (1, 0, 1), (1, 2, 1), (-1, 2, -1)], [(-1, 0, 1), (1, 0, -1), (1, 2, -1), (-1, 2, 1)]]
pos = [p for q in quads for p in q]
uv = [(0, 1), (1, 1), (1, 0), (0, 0)] * 2
idx = [0, 1, 2, 0, 2, 3, 4, 5, 6, 4, 6, 7]
data = b''.join(struct.pack('<3f', *p) for p in pos) + b''.join(struct.pack('<2f', *t) for t in uv) + struct.pack('<12H', *idx)
g = {
  "asset": {"version": "2.0"}, "scene": 0, "scenes": [{"nodes": [0]}], "nodes": [{"mesh": 0}],
  "meshes": [{"primitives": [{"attributes": {"POSITION": 0, "TEXCOORD_0": 1}, "indices": 2, "material": 0}]}],
  "materials": [{"alphaMode": mode, "doubleSided": True, "pbrMetallicRoughness": {"baseColorTexture": {"index": 0}}}],
  "textures": [{"sampler": 0, "source": 0}], "samplers": [{"magFilter": 9728, "wrapS": 33071, "wrapT": 33071}],
  "images": [{"uri": "data:image/png;base64," + base64.b64encode(png).decode()}],
  "buffers": [{"byteLength": len(data), "uri": "data:application/octet-stream;base64," + base64.b64encode(data).decode()}],
  "bufferViews": [{"buffer": 0, "byteOffset": 0, "byteLength": 96}, {"buffer": 0, "byteOffset": 96, "byteLength": 64},
                  {"buffer": 0, "byteOffset": 160, "byteLength": 24}],
  "accessors": [{"bufferView": 0, "componentType": 5126, "count": 8, "type": "VEC3", "min": [-1, 0, -1], "max": [1, 2, 1]},
                {"bufferView": 1, "componentType": 5126, "count": 8, "type": "VEC2"},
                {"bufferView": 2, "componentType": 5123, "count": 12, "type": "SCALAR"}],
}
open(f"fence-{mode.lower()}.gltf", "w").write(json.dumps(g))
