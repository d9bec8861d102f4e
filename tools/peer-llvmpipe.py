#!/usr/bin/env python3
"""Times Mesa's llvmpipe (a software OpenGL rasterizer) drawing a model exported by
`pixelflow-sim export`: the Gouraud mesh (`--mesh`, vertex colours) or the lightmap (texture
coordinate set 1 into the sRGB PNG pages, bilinear within the two nearest mip levels and
blended between them, GL_LINEAR_MIPMAP_LINEAR, as `render --method texture-bilinear` samples
under minification), from the file's camera, into a W x H colour and
depth framebuffer. Prints the median frame time over the frames (each one a clear, the draw
calls and a glFinish), the renderer string and the model's size, as JSON.

The peer for the frame-time ratios in docs/performance.md. Needs Debian's libegl1,
libegl-mesa0, libgl1-mesa-dri and libgbm1, and PyPI's moderngl, pygltflib, numpy and pillow:

    apt-get install -y libegl1 libegl-mesa0 libgl1-mesa-dri libgbm1
    pip install moderngl pygltflib numpy pillow
    EGL_PLATFORM=surfaceless python3 tools/peer-llvmpipe.py mesh.glb --size 1024 --frames 20

llvmpipe runs on every core (LP_NUM_THREADS, default the core count), as the project's frames
do. The textures are the 8-bit PNG pages (the project samples f32 texels): a cheaper texel
format for the peer, not a dearer one.
"""

import argparse
import io
import json
import math
import statistics
import time

import moderngl
import numpy as np
import pygltflib
from PIL import Image

COMPONENTS = {"SCALAR": 1, "VEC2": 2, "VEC3": 3, "VEC4": 4}
DTYPES = {5120: np.int8, 5121: np.uint8, 5122: np.int16, 5123: np.uint16, 5125: np.uint32,
          5126: np.float32}


def accessor(g, blob, index):
    """The accessor's elements as a 2-D numpy array (one row per element)."""
    a = g.accessors[index]
    view = g.bufferViews[a.bufferView]
    dtype = np.dtype(DTYPES[a.componentType])
    n = COMPONENTS[a.type]
    start = (view.byteOffset or 0) + (a.byteOffset or 0)
    stride = view.byteStride or dtype.itemsize * n
    raw = np.frombuffer(blob, dtype=np.uint8, count=stride * (a.count - 1) + dtype.itemsize * n,
                        offset=start)
    rows = np.lib.stride_tricks.as_strided(raw, shape=(a.count, dtype.itemsize * n),
                                           strides=(stride, 1))
    out = np.ascontiguousarray(rows).view(dtype).reshape(a.count, n)
    if a.normalized and dtype != np.float32:
        out = out.astype(np.float32) / np.iinfo(dtype).max
    return out


def quat_matrix(q):
    x, y, z, w = q
    return np.array([
        [1 - 2 * (y * y + z * z), 2 * (x * y - z * w), 2 * (x * z + y * w)],
        [2 * (x * y + z * w), 1 - 2 * (x * x + z * z), 2 * (y * z - x * w)],
        [2 * (x * z - y * w), 2 * (y * z + x * w), 1 - 2 * (x * x + y * y)],
    ])


def camera_matrix(g, aspect):
    """Projection x view of the file's camera node (glTF cameras look down -Z, +Y up)."""
    node = next(n for n in g.nodes if n.camera is not None)
    cam = g.cameras[node.camera]
    r = quat_matrix(node.rotation or [0, 0, 0, 1])
    t = np.array(node.translation or [0, 0, 0])
    view = np.eye(4)
    view[:3, :3] = r.T
    view[:3, 3] = -r.T @ t
    if cam.type == "perspective":
        p = cam.perspective
        f = 1.0 / math.tan(p.yfov / 2)
        n, fa = p.znear, (p.zfar or p.znear * 1e6)
        proj = np.array([[f / aspect, 0, 0, 0], [0, f, 0, 0],
                         [0, 0, (fa + n) / (n - fa), 2 * fa * n / (n - fa)], [0, 0, -1, 0]])
    else:
        o = cam.orthographic
        n, fa = o.znear, o.zfar
        proj = np.array([[1 / o.xmag, 0, 0, 0], [0, 1 / o.ymag, 0, 0],
                         [0, 0, 2 / (n - fa), (fa + n) / (n - fa)], [0, 0, 0, 1]])
    return (proj @ view).astype(np.float32)


VERTEX = """
#version 330
uniform mat4 mvp;
in vec3 position;
in vec3 attr;
out vec3 v_attr;
void main() { v_attr = attr; gl_Position = mvp * vec4(position, 1.0); }
"""
GOURAUD = """
#version 330
in vec3 v_attr;
out vec4 colour;
void main() { colour = vec4(v_attr, 1.0); }
"""
LIGHTMAP = """
#version 330
uniform sampler2D page;
in vec3 v_attr;
out vec4 colour;
void main() { colour = texture(page, v_attr.xy); }
"""


def load(ctx, g, blob):
    """Vertex arrays (and their texture pages) of every primitive of the file."""
    textures = {}
    draws = []
    for mesh in g.meshes:
        for prim in mesh.primitives:
            pos = accessor(g, blob, prim.attributes.POSITION)
            idx = accessor(g, blob, prim.indices).astype(np.uint32).ravel()
            page = None
            if prim.attributes.COLOR_0 is not None:
                attr = accessor(g, blob, prim.attributes.COLOR_0)[:, :3].astype(np.float32)
                prog = GOURAUD
            else:
                uv = accessor(g, blob, prim.attributes.TEXCOORD_1).astype(np.float32)
                attr = np.hstack([uv, np.zeros((len(uv), 1), np.float32)])
                prog = LIGHTMAP
                tex = g.materials[prim.material].emissiveTexture or \
                    g.materials[prim.material].pbrMetallicRoughness.baseColorTexture
                image = g.textures[tex.index].source
                if image not in textures:
                    iv = g.bufferViews[g.images[image].bufferView]
                    data = blob[iv.byteOffset or 0:(iv.byteOffset or 0) + iv.byteLength]
                    img = Image.open(io.BytesIO(data)).convert("RGBA")
                    t = ctx.texture(img.size, 4, img.tobytes())
                    t.build_mipmaps()
                    t.filter = (moderngl.LINEAR_MIPMAP_LINEAR, moderngl.LINEAR)
                    textures[image] = t
                page = textures[image]
            program = ctx.program(vertex_shader=VERTEX, fragment_shader=prog)
            vbo = ctx.buffer(np.hstack([pos.astype(np.float32), attr]).tobytes())
            ibo = ctx.buffer(idx.tobytes())
            vao = ctx.vertex_array(program, [(vbo, "3f 3f", "position", "attr")], ibo)
            draws.append((program, vao, page, len(idx) // 3))
    return draws


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("glb")
    ap.add_argument("--size", type=int, default=1024)
    ap.add_argument("--frames", type=int, default=20)
    ap.add_argument("--png", help="also write the last frame here (to check the view)")
    args = ap.parse_args()
    g = pygltflib.GLTF2().load(args.glb)
    blob = g.binary_blob()
    ctx = moderngl.create_context(standalone=True, backend="egl")
    draws = load(ctx, g, blob)
    mvp = camera_matrix(g, 1.0)
    fbo = ctx.simple_framebuffer((args.size, args.size), components=4)
    fbo.use()
    ctx.enable(moderngl.DEPTH_TEST)
    for program, _, _, _ in draws:
        program["mvp"].write(mvp.T.tobytes())
    times = []
    for k in range(args.frames + 3):
        t0 = time.perf_counter()
        fbo.clear(0.0, 0.0, 0.0, 1.0, depth=1.0)
        for program, vao, page, _ in draws:
            if page is not None:
                page.use(0)
            vao.render(moderngl.TRIANGLES)
        ctx.finish()
        if k >= 3:
            times.append((time.perf_counter() - t0) * 1e3)
    if args.png:
        pixels = np.frombuffer(fbo.read(components=3), np.uint8)
        img = pixels.reshape(args.size, args.size, 3)[::-1]
        Image.fromarray(img).save(args.png)
    print(json.dumps({
        "renderer": ctx.info["GL_RENDERER"],
        "file": args.glb,
        "size": args.size,
        "triangles": sum(d[3] for d in draws),
        "draws": len(draws),
        "frame_ms_median": round(statistics.median(times), 3),
        "frame_ms_min": round(min(times), 3),
    }))


if __name__ == "__main__":
    main()
