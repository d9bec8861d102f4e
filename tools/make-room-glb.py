#!/usr/bin/env python3
"""Writes scenes/gltf/room.glb: a small glTF 2.0 binary laid out the way Blender's exporter
writes one (y up, one node per object, flat-shaded faces with their own vertices and normals,
materials with `doubleSided`, the emission strength in KHR_materials_emissive_strength).

The model: a closed box room 4 m (x) by 2.5 m (y) by 5 m (z), its 6 faces as 12 triangles with
fronts facing in (floor one material, walls and ceiling another); a 1 m square ceiling panel
hanging 0.2 m below the ceiling, facing down, whose doubleSided material emits
(emissiveFactor 1, 1, 1 times emissiveStrength 10), so it lights the room and the ceiling above
it; and a camera near the +z wall at eye height, tilted 10 degrees down, looking along -z.

Plain Python standard library; the same bytes every run. Usage, from the repository root:

    python3 tools/make-room-glb.py [output.glb]
"""

import json
import math
import struct
import sys

# The room's extent: x in [-2, 2], y in [0, 2.5], z in [-2.5, 2.5].
X, Y, Z = 2.0, 2.5, 2.5


def room_faces():
    """The room's faces as (corners counter-clockwise seen from inside, inward normal)."""
    lo, hi = (-X, 0.0, -Z), (X, Y, Z)

    def p(ix, iy, iz):
        return (
            (lo[0], hi[0])[ix],
            (lo[1], hi[1])[iy],
            (lo[2], hi[2])[iz],
        )

    floor = ([p(0, 0, 0), p(0, 0, 1), p(1, 0, 1), p(1, 0, 0)], (0.0, 1.0, 0.0))
    walls = [
        ([p(0, 1, 0), p(1, 1, 0), p(1, 1, 1), p(0, 1, 1)], (0.0, -1.0, 0.0)),  # ceiling
        ([p(0, 0, 0), p(1, 0, 0), p(1, 1, 0), p(0, 1, 0)], (0.0, 0.0, 1.0)),  # back, z = -2.5
        ([p(1, 0, 1), p(0, 0, 1), p(0, 1, 1), p(1, 1, 1)], (0.0, 0.0, -1.0)),  # front, z = 2.5
        ([p(0, 0, 1), p(0, 0, 0), p(0, 1, 0), p(0, 1, 1)], (1.0, 0.0, 0.0)),  # left, x = -2
        ([p(1, 0, 0), p(1, 0, 1), p(1, 1, 1), p(1, 1, 0)], (-1.0, 0.0, 0.0)),  # right, x = 2
    ]
    return [floor], walls


def panel_faces():
    """The panel in its node's frame: a 1 m square in y = 0, front down (-y)."""
    h = 0.5
    corners = [(-h, 0.0, -h), (h, 0.0, -h), (h, 0.0, h), (-h, 0.0, h)]
    return [(corners, (0.0, -1.0, 0.0))]


class Writer:
    """One binary buffer, and the bufferViews and accessors that describe it."""

    def __init__(self):
        self.bin = bytearray()
        self.views = []
        self.accessors = []

    def view(self, data, target):
        while len(self.bin) % 4:
            self.bin.append(0)
        self.views.append(
            {"buffer": 0, "byteLength": len(data), "byteOffset": len(self.bin), "target": target}
        )
        self.bin += data
        return len(self.views) - 1

    def vec3(self, values, with_bounds):
        data = b"".join(struct.pack("<3f", *v) for v in values)
        accessor = {
            "bufferView": self.view(data, 34962),
            "componentType": 5126,
            "count": len(values),
            "type": "VEC3",
        }
        if with_bounds:
            accessor["min"] = [min(v[k] for v in values) for k in range(3)]
            accessor["max"] = [max(v[k] for v in values) for k in range(3)]
        self.accessors.append(accessor)
        return len(self.accessors) - 1

    def indices(self, values):
        data = b"".join(struct.pack("<H", i) for i in values)
        self.accessors.append(
            {
                "bufferView": self.view(data, 34963),
                "componentType": 5123,
                "count": len(values),
                "type": "SCALAR",
            }
        )
        return len(self.accessors) - 1

    def primitive(self, faces, material):
        """Quads as two triangles each (0 1 2, 0 2 3), every face with its own vertices."""
        positions, normals, indices = [], [], []
        for corners, normal in faces:
            base = len(positions)
            positions += corners
            normals += [normal] * 4
            indices += [base, base + 1, base + 2, base, base + 2, base + 3]
        return {
            "attributes": {
                "POSITION": self.vec3(positions, True),
                "NORMAL": self.vec3(normals, False),
            },
            "indices": self.indices(indices),
            "material": material,
        }


def material(name, colour, emissive=None):
    m = {
        "doubleSided": True,
        "name": name,
        "pbrMetallicRoughness": {
            "baseColorFactor": [*colour, 1.0],
            "metallicFactor": 0.0,
            "roughnessFactor": 0.5,
        },
    }
    if emissive is not None:
        m["emissiveFactor"] = [1.0, 1.0, 1.0]
        m["extensions"] = {"KHR_materials_emissive_strength": {"emissiveStrength": emissive}}
    return m


def document():
    w = Writer()
    floor, walls = room_faces()
    room = {"name": "Cube", "primitives": [w.primitive(floor, 0), w.primitive(walls, 1)]}
    panel = {"name": "Plane", "primitives": [w.primitive(panel_faces(), 2)]}
    # Tilted 10 degrees down: a rotation of -10 degrees about x, as a quaternion (x, y, z, w).
    half = math.radians(-10.0) / 2
    tilt = [math.sin(half), 0.0, 0.0, math.cos(half)]
    gltf = {
        "asset": {"generator": "pixelflow-sim tools/make-room-glb.py", "version": "2.0"},
        "extensionsUsed": ["KHR_materials_emissive_strength"],
        "scene": 0,
        "scenes": [{"name": "Scene", "nodes": [0, 1, 2]}],
        "nodes": [
            {"mesh": 0, "name": "Room"},
            {"mesh": 1, "name": "Panel", "translation": [0.0, 2.3, 0.0]},
            {"camera": 0, "name": "Camera", "rotation": tilt, "translation": [0.0, 1.6, 2.2]},
        ],
        "cameras": [
            {
                "name": "Camera",
                "type": "perspective",
                "perspective": {
                    "aspectRatio": 4.0 / 3.0,
                    "yfov": 0.9,
                    "zfar": 100.0,
                    "znear": 0.1,
                },
            }
        ],
        "materials": [
            material("Floor", [0.6, 0.45, 0.3]),
            material("Wall", [0.8, 0.8, 0.8]),
            material("Panel", [0.8, 0.8, 0.8], emissive=10.0),
        ],
        "meshes": [room, panel],
        "accessors": w.accessors,
        "bufferViews": w.views,
        "buffers": [{"byteLength": len(w.bin)}],
    }
    return gltf, bytes(w.bin)


def glb(gltf, bin_chunk):
    """The GLB container: header, JSON chunk padded with spaces, BIN chunk padded with zeros."""
    text = json.dumps(gltf, separators=(",", ":")).encode()
    text += b" " * (-len(text) % 4)
    bin_chunk += b"\0" * (-len(bin_chunk) % 4)
    total = 12 + 8 + len(text) + 8 + len(bin_chunk)
    return (
        struct.pack("<4sII", b"glTF", 2, total)
        + struct.pack("<I4s", len(text), b"JSON")
        + text
        + struct.pack("<I4s", len(bin_chunk), b"BIN\0")
        + bin_chunk
    )


def main():
    out = sys.argv[1] if len(sys.argv) > 1 else "scenes/gltf/room.glb"
    data = glb(*document())
    with open(out, "wb") as f:
        f.write(data)
    print(f"{out}: {len(data)} bytes")


if __name__ == "__main__":
    main()
