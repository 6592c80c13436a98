#!/usr/bin/env python3
"""Writes pool_dolly_cam.gltf: the camera of scenes/pool.toml as a glTF camera, the way Blender or
Maya export one (a node "DollyCam" carrying a perspective camera, moved by an animation
"DollyMove" with LINEAR translation and rotation keys; the buffer embedded as a data: URI).

The keys are pool.toml's three camera keys (frames 1, 24, 48 at 24 fps): the same eyes, each
looking at its key's target with no roll (yaw about +y, then pitch about x; glTF cameras look
down -Z with +Y up). Between keys glTF interpolates linearly (slerp for rotations) where
pool.toml's keyframes use smooth C1 curves, so the two agree at the keys only.

    python3 scenes/assets/make_pool_dolly_cam.py   # rewrites scenes/assets/pool_dolly_cam.gltf
"""
import base64
import json
import math
import os
import struct

FPS = 24.0
KEYS = [  # (frame, eye, target) from scenes/pool.toml
    (1, (-2.2, 2.3, -4.1), (0.2, -1.3, 0.9)),
    (24, (-0.6, 2.35, -4.25), (0.9, -1.35, 0.9)),
    (48, (1.0, 2.4, -4.2), (1.6, -1.4, 0.8)),
]
YFOV_DEG = 55.0
ASPECT = 16.0 / 9.0


def quat_mul(a, b):
    ax, ay, az, aw = a
    bx, by, bz, bw = b
    return (
        aw * bx + ax * bw + ay * bz - az * by,
        aw * by - ax * bz + ay * bw + az * bx,
        aw * bz + ax * by - ay * bx + az * bw,
        aw * bw - ax * bx - ay * by - az * bz,
    )


def look_rotation(eye, target):
    """The rotation taking -Z to the view direction with +Y kept upright (no roll)."""
    d = [t - e for t, e in zip(target, eye)]
    yaw = math.atan2(-d[0], -d[2])  # about +y: -Z turns toward (d.x, d.z)
    pitch = math.atan2(d[1], math.hypot(d[0], d[2]))  # about the turned x axis
    q_yaw = (0.0, math.sin(yaw / 2), 0.0, math.cos(yaw / 2))
    q_pitch = (math.sin(pitch / 2), 0.0, 0.0, math.cos(pitch / 2))
    return quat_mul(q_yaw, q_pitch)


def main():
    times = [(frame - 1) / FPS for frame, _, _ in KEYS]
    translations = [c for _, eye, _ in KEYS for c in eye]
    rotations = [c for _, eye, target in KEYS for c in look_rotation(eye, target)]
    blobs = [times, translations, rotations]
    data = b""
    views = []
    for blob in blobs:
        views.append({"buffer": 0, "byteOffset": len(data), "byteLength": 4 * len(blob)})
        data += struct.pack("<%df" % len(blob), *blob)
    accessors = [
        {"bufferView": 0, "componentType": 5126, "count": len(times), "type": "SCALAR",
         "min": [min(times)], "max": [max(times)]},
        {"bufferView": 1, "componentType": 5126, "count": len(KEYS), "type": "VEC3"},
        {"bufferView": 2, "componentType": 5126, "count": len(KEYS), "type": "VEC4"},
    ]
    gltf = {
        "asset": {"version": "2.0", "generator": "scenes/assets/make_pool_dolly_cam.py"},
        "scene": 0,
        "scenes": [{"nodes": [0]}],
        "nodes": [{
            "name": "DollyCam", "camera": 0,
            "translation": list(KEYS[0][1]),
            "rotation": list(look_rotation(KEYS[0][1], KEYS[0][2])),
        }],
        "cameras": [{"name": "DollyCamData", "type": "perspective", "perspective": {
            "yfov": math.radians(YFOV_DEG), "aspectRatio": ASPECT, "znear": 0.05, "zfar": 1000.0}}],
        "animations": [{
            "name": "DollyMove",
            "samplers": [
                {"input": 0, "output": 1, "interpolation": "LINEAR"},
                {"input": 0, "output": 2, "interpolation": "LINEAR"},
            ],
            "channels": [
                {"sampler": 0, "target": {"node": 0, "path": "translation"}},
                {"sampler": 1, "target": {"node": 0, "path": "rotation"}},
            ],
        }],
        "buffers": [{
            "byteLength": len(data),
            "uri": "data:application/octet-stream;base64," + base64.b64encode(data).decode(),
        }],
        "bufferViews": views,
        "accessors": accessors,
    }
    path = os.path.join(os.path.dirname(os.path.abspath(__file__)), "pool_dolly_cam.gltf")
    with open(path, "w") as f:
        json.dump(gltf, f, indent=1)
        f.write("\n")


if __name__ == "__main__":
    main()
