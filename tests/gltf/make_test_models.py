#!/usr/bin/env python3
"""Writes the small glTF models that tests/characters.rs loads. Python 3 standard library only.

The Khronos sample characters use only LINEAR keys, JOINTS_0 and embedded buffers; these files
cover the rest. Every number in them is chosen so the expected poses can be worked out by hand
(the tests write the working out next to the assertions).

Run from the repository root:  python3 tests/gltf/make_test_models.py

Files written (in tests/gltf/):
  step.gltf               two-joint rig, STEP translation/rotation/scale channels (embedded buffer)
  cubic.gltf              same rig, CUBICSPLINE translation/rotation/scale channels
  eight_influences.glb    8 joints; vertex 0 has 8 influences (JOINTS_0 u16 + JOINTS_1 u8,
                          WEIGHTS_0 float + WEIGHTS_1 normalised u8, summing to 3 before
                          normalisation)
  external.gltf + external.bin + external_texture.png
                          unskinned, node hierarchy (matrix parent, TRS child), four primitives:
                          triangles (textured, no normals), strip, fan, points (skipped); a
                          LINEAR rotation animation and a morph-target weights channel (ignored)
  joint_out_of_range.gltf vertex 1 uses joint 5 of a 2-joint skin
  zero_weights.gltf       vertex 2 has all weights zero
  short_buffer.gltf + short_buffer.bin
                          buffer byteLength says 10 bytes more than short_buffer.bin holds
  missing_buffer.gltf     refers to a .bin that does not exist
"""
import base64
import json
import math
import os
import struct
import zlib

HERE = os.path.dirname(os.path.abspath(__file__))

FLOAT, UBYTE, USHORT, UINT = 5126, 5121, 5123, 5125
FORMAT = {FLOAT: "f", UBYTE: "B", USHORT: "H", UINT: "I"}
H = math.sqrt(0.5)  # sin 45 = cos 45: the quaternion of 90 degrees about z is (0, 0, H, H)


class Builder:
    """Accumulates one binary buffer with one buffer view per accessor."""

    def __init__(self):
        self.bin = bytearray()
        self.views = []
        self.accessors = []

    def add(self, component, type_, rows, normalized=False, minmax=False):
        while len(self.bin) % 4:
            self.bin.append(0)
        offset = len(self.bin)
        fmt = FORMAT[component]
        for row in rows:
            self.bin += struct.pack("<" + fmt * len(row), *row)
        self.views.append({"buffer": 0, "byteOffset": offset, "byteLength": len(self.bin) - offset})
        accessor = {
            "bufferView": len(self.views) - 1,
            "componentType": component,
            "count": len(rows),
            "type": type_,
        }
        if normalized:
            accessor["normalized"] = True
        if minmax:
            accessor["min"] = [min(r[i] for r in rows) for i in range(len(rows[0]))]
            accessor["max"] = [max(r[i] for r in rows) for i in range(len(rows[0]))]
        self.accessors.append(accessor)
        return len(self.accessors) - 1

    def scalars(self, values, component=FLOAT):
        return self.add(component, "SCALAR", [[v] for v in values])

    def finish(self):
        while len(self.bin) % 4:
            self.bin.append(0)
        return bytes(self.bin)


def document(builder, **parts):
    doc = {"asset": {"version": "2.0", "generator": "snell tests/gltf/make_test_models.py"}}
    doc.update(parts)
    doc["bufferViews"] = builder.views
    doc["accessors"] = builder.accessors
    return doc


def write_embedded(name, doc, data):
    doc["buffers"] = [
        {
            "byteLength": len(data),
            "uri": "data:application/octet-stream;base64," + base64.b64encode(data).decode(),
        }
    ]
    with open(os.path.join(HERE, name), "w") as f:
        json.dump(doc, f, indent=1)
        f.write("\n")


def write_external(name, bin_name, doc, data, declared_length=None):
    doc["buffers"] = [{"byteLength": declared_length or len(data), "uri": bin_name}]
    with open(os.path.join(HERE, name), "w") as f:
        json.dump(doc, f, indent=1)
        f.write("\n")
    with open(os.path.join(HERE, bin_name), "wb") as f:
        f.write(data)


def write_glb(name, doc, data):
    doc["buffers"] = [{"byteLength": len(data)}]
    text = json.dumps(doc).encode()
    text += b" " * ((4 - len(text) % 4) % 4)
    total = 12 + 8 + len(text) + 8 + len(data)
    out = struct.pack("<4sII", b"glTF", 2, total)
    out += struct.pack("<II", len(text), 0x4E4F534A) + text
    out += struct.pack("<II", len(data), 0x004E4942) + data
    with open(os.path.join(HERE, name), "wb") as f:
        f.write(out)


def png_rgba(width, height, rows):
    """8-bit RGBA PNG; rows top first, each a list of (r, g, b, a)."""

    def chunk(kind, payload):
        return (
            struct.pack(">I", len(payload))
            + kind
            + payload
            + struct.pack(">I", zlib.crc32(kind + payload) & 0xFFFFFFFF)
        )

    raw = b"".join(b"\x00" + bytes(c for pixel in row for c in pixel) for row in rows)
    return (
        b"\x89PNG\r\n\x1a\n"
        + chunk(b"IHDR", struct.pack(">IIBBBBB", width, height, 8, 6, 0, 0, 0))
        + chunk(b"IDAT", zlib.compress(raw))
        + chunk(b"IEND", b"")
    )


def two_joint_rig(builder, joints=None, weights=None):
    """The rig shared by step/cubic and the broken files.

    Nodes: 0 root (children 1, 3); 1 J0 at the origin (child 2); 2 J1 translated (0, 1, 0);
    3 the skinned mesh. Skin joints [1, 2], inverse binds identity and translate(0, -1, 0).
    Vertices: v0 (0,0,0) on J0, v1 (1,1,0) on J1, v2 (0,2,0) half J0 half J1; normals +z.
    """
    positions = builder.add(FLOAT, "VEC3", [[0, 0, 0], [1, 1, 0], [0, 2, 0]], minmax=True)
    normals = builder.add(FLOAT, "VEC3", [[0, 0, 1]] * 3)
    joints = builder.add(UBYTE, "VEC4", joints or [[0, 0, 0, 0], [1, 0, 0, 0], [0, 1, 0, 0]])
    weights = builder.add(FLOAT, "VEC4", weights or [[1, 0, 0, 0], [1, 0, 0, 0], [0.5, 0.5, 0, 0]])
    indices = builder.scalars([0, 1, 2], USHORT)
    ibm = builder.add(
        FLOAT,
        "MAT4",
        [
            [1, 0, 0, 0, 0, 1, 0, 0, 0, 0, 1, 0, 0, 0, 0, 1],
            [1, 0, 0, 0, 0, 1, 0, 0, 0, 0, 1, 0, 0, -1, 0, 1],  # column-major: translation in 12..14
        ],
    )
    parts = {
        "scene": 0,
        "scenes": [{"nodes": [0]}],
        "nodes": [
            {"name": "root", "children": [1, 3]},
            {"name": "J0", "children": [2]},
            {"name": "J1", "translation": [0, 1, 0]},
            {"name": "skinned", "mesh": 0, "skin": 0},
        ],
        "skins": [{"joints": [1, 2], "inverseBindMatrices": ibm}],
        "meshes": [
            {
                "name": "rig",
                "primitives": [
                    {
                        "attributes": {
                            "POSITION": positions,
                            "NORMAL": normals,
                            "JOINTS_0": joints,
                            "WEIGHTS_0": weights,
                        },
                        "indices": indices,
                    }
                ],
            }
        ],
    }
    return parts


def channel_set(builder, interpolation, tracks):
    """tracks: list of (path, times, values, type)."""
    samplers, channels = [], []
    for path, times, values, type_ in tracks:
        samplers.append(
            {
                "input": builder.scalars(times),
                "output": builder.add(FLOAT, type_, values),
                "interpolation": interpolation,
            }
        )
        channels.append({"sampler": len(samplers) - 1, "target": {"node": 2, "path": path}})
    return {"samplers": samplers, "channels": channels}


def make_step():
    b = Builder()
    parts = two_joint_rig(b)
    anim = channel_set(
        b,
        "STEP",
        [
            ("translation", [0, 1, 2], [[0, 1, 0], [1, 1, 0], [2, 1, 0]], "VEC3"),
            ("rotation", [0, 1], [[0, 0, 0, 1], [0, 0, H, H]], "VEC4"),
            ("scale", [0.5, 1.5], [[1, 1, 1], [2, 2, 2]], "VEC3"),
        ],
    )
    anim["name"] = "Steps"
    write_embedded("step.gltf", document(b, animations=[anim], **parts), b.finish())


def make_cubic():
    b = Builder()
    parts = two_joint_rig(b)
    # Triples per key: in-tangent, value, out-tangent.
    anim = channel_set(
        b,
        "CUBICSPLINE",
        [
            (
                "translation",
                [0, 2],
                [[0, 0, 0], [0, 1, 0], [3, 0, 0], [-1, 0, 0], [10, 1, 0], [0, 0, 0]],
                "VEC3",
            ),
            (
                "rotation",
                [0, 2],
                [[0, 0, 0, 0], [0, 0, 0, 1], [0, 0, 0, 0], [0, 0, 0, 0], [0, 0, H, H], [0, 0, 0, 0]],
                "VEC4",
            ),
            (
                "scale",
                [0, 2],
                [[0, 0, 0], [1, 1, 1], [1, 0, 0], [0, 0, 0], [3, 3, 3], [0, 0, 0]],
                "VEC3",
            ),
        ],
    )
    anim["name"] = "Smooth"
    write_embedded("cubic.gltf", document(b, animations=[anim], **parts), b.finish())


def make_eight_influences():
    """Joints k = 0..7 are nodes 1..8, children of node 0, translated by d_k = (k+1, 10*(k%2), -k);
    inverse binds identity, so joint matrix k = translate(d_k)."""
    b = Builder()
    positions = b.add(FLOAT, "VEC3", [[0, 0, 0], [1, 0, 0], [0, 1, 0]], minmax=True)
    normals = b.add(FLOAT, "VEC3", [[0, 0, 1]] * 3)
    joints0 = b.add(USHORT, "VEC4", [[7, 6, 5, 4], [3, 0, 0, 0], [2, 0, 0, 0]])
    weights0 = b.add(FLOAT, "VEC4", [[0.1, 0.2, 0.3, 0.4], [1, 0, 0, 0], [2, 0, 0, 0]])
    joints1 = b.add(UBYTE, "VEC4", [[3, 2, 1, 0], [0, 0, 0, 0], [0, 0, 0, 0]])
    # Normalised u8: 51/255 = 0.2, 102/255 = 0.4, 153/255 = 0.6, 204/255 = 0.8.
    weights1 = b.add(UBYTE, "VEC4", [[51, 102, 153, 204], [0, 0, 0, 0], [0, 0, 0, 0]], normalized=True)
    indices = b.scalars([0, 1, 2], UBYTE)
    nodes = [{"name": "root", "children": list(range(1, 10))}]
    for k in range(8):
        nodes.append({"name": f"J{k}", "translation": [k + 1, 10 * (k % 2), -k]})
    nodes.append({"name": "skinned", "mesh": 0, "skin": 0})
    doc = document(
        b,
        scene=0,
        scenes=[{"nodes": [0]}],
        nodes=nodes,
        skins=[{"joints": list(range(1, 9))}],
        meshes=[
            {
                "name": "eight",
                "primitives": [
                    {
                        "attributes": {
                            "POSITION": positions,
                            "NORMAL": normals,
                            "JOINTS_0": joints0,
                            "WEIGHTS_0": weights0,
                            "JOINTS_1": joints1,
                            "WEIGHTS_1": weights1,
                        },
                        "indices": indices,
                    }
                ],
            }
        ],
    )
    write_glb("eight_influences.glb", doc, b.finish())


def make_external():
    """Node 0 "parent": matrix = translate(0, 0, -5) * scale(2) (column-major below); node 1
    "child": translation (1, 0, 0), rotation 90 degrees about z; draws mesh 0."""
    b = Builder()
    quad = b.add(FLOAT, "VEC3", [[0, 0, 0], [1, 0, 0], [1, 1, 0], [0, 1, 0]], minmax=True)
    uvs = b.add(FLOAT, "VEC2", [[0, 1], [1, 1], [1, 0], [0, 0]])
    quad_indices = b.scalars([0, 1, 2, 0, 2, 3], USHORT)
    morph = b.add(FLOAT, "VEC3", [[0, 0, 0]] * 4, minmax=True)
    strip = b.add(FLOAT, "VEC3", [[0, 0, 1], [1, 0, 1], [0, 1, 1], [1, 1, 1]], minmax=True)
    fan = b.add(FLOAT, "VEC3", [[0, 0, 2], [1, 0, 2], [1, 1, 2], [0, 1, 2]], minmax=True)
    points = b.add(FLOAT, "VEC3", [[0, 0, 3], [1, 0, 3]], minmax=True)
    times = b.scalars([0, 1])
    rotations = b.add(FLOAT, "VEC4", [[0, 0, H, H], [0, 0, 1, 0]])  # 90 then 180 degrees about z
    weight_times = b.scalars([0, 1])
    weight_values = b.scalars([0, 1])
    doc = document(
        b,
        scene=0,
        scenes=[{"nodes": [0]}],
        nodes=[
            {
                "name": "parent",
                "children": [1],
                "matrix": [2, 0, 0, 0, 0, 2, 0, 0, 0, 0, 2, 0, 0, 0, -5, 1],
            },
            {"name": "child", "mesh": 0, "translation": [1, 0, 0], "rotation": [0, 0, H, H]},
        ],
        meshes=[
            {
                "name": "shapes",
                "weights": [0],
                "primitives": [
                    {
                        "attributes": {"POSITION": quad, "TEXCOORD_0": uvs},
                        "indices": quad_indices,
                        "material": 0,
                        "targets": [{"POSITION": morph}],
                    },
                    {"attributes": {"POSITION": strip}, "mode": 5},
                    {"attributes": {"POSITION": fan}, "mode": 6},
                    {"attributes": {"POSITION": points}, "mode": 0},
                ],
            }
        ],
        materials=[
            {
                "name": "tinted",
                "pbrMetallicRoughness": {
                    "baseColorFactor": [0.5, 0.25, 1.0, 1.0],
                    "baseColorTexture": {"index": 0},
                },
            }
        ],
        textures=[{"source": 0}],
        images=[{"uri": "external_texture.png", "name": "checker"}],
        animations=[
            {
                "name": "Spin",
                "samplers": [
                    {"input": times, "output": rotations},
                    {"input": weight_times, "output": weight_values},
                ],
                "channels": [
                    {"sampler": 0, "target": {"node": 1, "path": "rotation"}},
                    {"sampler": 1, "target": {"node": 1, "path": "weights"}},
                ],
            }
        ],
    )
    write_external("external.gltf", "external.bin", doc, b.finish())
    # 2 x 2, top row red then green, bottom row blue then half-transparent white.
    png = png_rgba(2, 2, [[(255, 0, 0, 255), (0, 255, 0, 255)], [(0, 0, 255, 255), (255, 255, 255, 128)]])
    with open(os.path.join(HERE, "external_texture.png"), "wb") as f:
        f.write(png)


def make_broken():
    b = Builder()
    parts = two_joint_rig(b, joints=[[0, 0, 0, 0], [5, 0, 0, 0], [0, 1, 0, 0]])
    write_embedded("joint_out_of_range.gltf", document(b, **parts), b.finish())

    b = Builder()
    parts = two_joint_rig(b, weights=[[1, 0, 0, 0], [1, 0, 0, 0], [0, 0, 0, 0]])
    write_embedded("zero_weights.gltf", document(b, **parts), b.finish())

    b = Builder()
    parts = two_joint_rig(b)
    data = b.finish()
    # The .bin is cut 10 bytes short of the byteLength the JSON declares (and the last views need).
    write_external("short_buffer.gltf", "short_buffer.bin", document(b, **parts), data[:-10], len(data))

    b = Builder()
    parts = two_joint_rig(b)
    doc = document(b, **parts)
    doc["buffers"] = [{"byteLength": len(b.finish()), "uri": "does_not_exist.bin"}]
    with open(os.path.join(HERE, "missing_buffer.gltf"), "w") as f:
        json.dump(doc, f, indent=1)
        f.write("\n")


if __name__ == "__main__":
    make_step()
    make_cubic()
    make_eight_influences()
    make_external()
    make_broken()
