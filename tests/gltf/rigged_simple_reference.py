#!/usr/bin/env python3
"""Reference poses of scenes/assets/RiggedSimple.glb, computed independently of snell.

Plain Python 3 (standard library only), double precision. Reads the GLB container and its JSON
by hand, samples the one animation with the glTF formulas (LINEAR: lerp for translation/scale,
shortest-path slerp for rotation; times clamped to the key range), builds node global matrices,
joint matrices global(joint) * inverseBind, and skins a few vertices:

    p' = sum_i w_i * J_i * p        (weights as stored; they already sum to 1)

The numbers printed are pasted into tests/characters.rs (rigged_simple_matches_reference_poses).
Run from the repository root:  python3 tests/gltf/rigged_simple_reference.py
"""
import json
import math
import struct

GLB = "scenes/assets/RiggedSimple.glb"
TIMES = [0.125, 0.3, 1.7]  # 0.125 is key 2 exactly; 0.3 and 1.7 lie between keys
VERTICES = [0, 20, 40, 80, 150]


def load():
    data = open(GLB, "rb").read()
    json_len = struct.unpack_from("<I", data, 12)[0]
    doc = json.loads(data[20 : 20 + json_len])
    bin_start = 20 + json_len + 8
    return doc, data, bin_start


def accessor(doc, data, bin_start, index):
    a = doc["accessors"][index]
    view = doc["bufferViews"][a["bufferView"]]
    n = {"SCALAR": 1, "VEC3": 3, "VEC4": 4, "MAT4": 16}[a["type"]]
    fmt = {5126: "f", 5123: "H", 5121: "B"}[a["componentType"]]
    size = struct.calcsize(fmt) * n
    stride = view.get("byteStride", size)
    base = bin_start + view.get("byteOffset", 0) + a.get("byteOffset", 0)
    return [list(struct.unpack_from("<" + fmt * n, data, base + k * stride)) for k in range(a["count"])]


def mat_from_column_major(m):
    # glTF stores matrices column-major; rows[r][c] = m[c * 4 + r]
    return [[m[c * 4 + r] for c in range(4)] for r in range(4)]


def matmul(a, b):
    return [[sum(a[r][k] * b[k][c] for k in range(4)) for c in range(4)] for r in range(4)]


def trs(t, q, s):
    x, y, z, w = q
    norm = math.sqrt(x * x + y * y + z * z + w * w)
    x, y, z, w = x / norm, y / norm, z / norm, w / norm
    r = [
        [1 - 2 * (y * y + z * z), 2 * (x * y - z * w), 2 * (x * z + y * w)],
        [2 * (x * y + z * w), 1 - 2 * (x * x + z * z), 2 * (y * z - x * w)],
        [2 * (x * z - y * w), 2 * (y * z + x * w), 1 - 2 * (x * x + y * y)],
    ]
    return [
        [r[0][0] * s[0], r[0][1] * s[1], r[0][2] * s[2], t[0]],
        [r[1][0] * s[0], r[1][1] * s[1], r[1][2] * s[2], t[1]],
        [r[2][0] * s[0], r[2][1] * s[1], r[2][2] * s[2], t[2]],
        [0.0, 0.0, 0.0, 1.0],
    ]


def slerp(a, b, s):
    d = sum(x * y for x, y in zip(a, b))
    if d < 0:
        b = [-x for x in b]
        d = -d
    if d > 1 - 1e-12:
        out = [x + (y - x) * s for x, y in zip(a, b)]
    else:
        theta = math.acos(min(d, 1.0))
        wa = math.sin((1 - s) * theta) / math.sin(theta)
        wb = math.sin(s * theta) / math.sin(theta)
        out = [wa * x + wb * y for x, y in zip(a, b)]
    n = math.sqrt(sum(x * x for x in out))
    return [x / n for x in out]


def sample(times, values, t, rotation):
    if t <= times[0]:
        return values[0]
    if t >= times[-1]:
        return values[-1]
    k = max(i for i in range(len(times)) if times[i] <= t)
    if times[k] == t:
        return values[k]
    s = (t - times[k]) / (times[k + 1] - times[k])
    if rotation:
        return slerp(values[k], values[k + 1], s)
    return [x + (y - x) * s for x, y in zip(values[k], values[k + 1])]


def main():
    doc, data, bin_start = load()
    acc = lambda i: accessor(doc, data, bin_start, i)
    nodes = doc["nodes"]
    skin = doc["skins"][0]
    ibm = [mat_from_column_major(m) for m in acc(skin["inverseBindMatrices"])]
    prim = doc["meshes"][0]["primitives"][0]
    positions = acc(prim["attributes"]["POSITION"])
    joints = acc(prim["attributes"]["JOINTS_0"])
    weights = acc(prim["attributes"]["WEIGHTS_0"])
    anim = doc["animations"][0]

    parent = {}
    for i, n in enumerate(nodes):
        for c in n.get("children", []):
            parent[c] = i

    for t in TIMES:
        local = {}
        animated = {}
        for ch in anim["channels"]:
            sampler = anim["samplers"][ch["sampler"]]
            assert sampler["interpolation"] == "LINEAR"
            times = [x[0] for x in acc(sampler["input"])]
            values = acc(sampler["output"])
            path = ch["target"]["path"]
            animated.setdefault(ch["target"]["node"], {})[path] = sample(times, values, t, path == "rotation")
        for i, n in enumerate(nodes):
            if "matrix" in n:
                local[i] = mat_from_column_major(n["matrix"])
            else:
                a = animated.get(i, {})
                local[i] = trs(
                    a.get("translation", n.get("translation", [0, 0, 0])),
                    a.get("rotation", n.get("rotation", [0, 0, 0, 1])),
                    a.get("scale", n.get("scale", [1, 1, 1])),
                )

        def glob(i):
            return matmul(glob(parent[i]), local[i]) if i in parent else local[i]

        joint_m = [matmul(glob(j), ibm[k]) for k, j in enumerate(skin["joints"])]
        print(f"// t = {t} s")
        for k, m in enumerate(joint_m):
            cols = [[m[r][c] for r in range(4)] for c in range(4)]
            flat = ", ".join(f"{v:.9e}" for col in cols for v in col)
            print(f"joint {k} (column-major): [{flat}]")
        for v in VERTICES:
            p = positions[v] + [1.0]
            out = [0.0, 0.0, 0.0]
            for ji, w in zip(joints[v], weights[v]):
                if w == 0:
                    continue
                m = joint_m[ji]
                for r in range(3):
                    out[r] += w * sum(m[r][c] * p[c] for c in range(4))
            print(f"vertex {v}: joints {joints[v]} weights {weights[v]} -> [{out[0]:.9e}, {out[1]:.9e}, {out[2]:.9e}]")


if __name__ == "__main__":
    main()
