"""Reads a snell frame with the pip `OpenEXR` module and checks it against the channel map
(README, "The EXR channel map") with nothing of snell's code: the Cryptomatte IDs from the pip
`mmh3` module, the masks decoded from the ranks against `IndexOB`, `Z` and `worldToNDC` against
the true positions, the effects' sum, the values where nothing is seen.

Usage: python3 exr_readers.py FRAME.exr OUT_DIR
Writes OUT_DIR/channels.json ({name: "HALF" | "FLOAT" | "UINT"}) and OUT_DIR/<name>.f32 (every
channel as little-endian float32, rows top first) for the Rust test to compare with snell's own
reader, and prints one line per check. Exits 1 with a message on the first failed check.
"""

import json
import sys
from fractions import Fraction
from pathlib import Path

import mmh3
import numpy as np
import OpenEXR

SKY_DEPTH_M = 1e10


def fail(message):
    print(f"FAIL: {message}", file=sys.stderr)
    sys.exit(1)


def check(condition, message):
    if not condition:
        fail(message)
    print(f"ok: {message}")


def cryptomatte_id_bits(name):
    """The specification's ID: MurmurHash3_32 of the UTF-8 name, its float exponent kept in 1..254."""
    h = mmh3.hash(name.encode("utf-8"), 0, signed=False)
    exponent = (h >> 23) & 0xFF
    if exponent in (0, 255):
        h ^= 1 << 23
    return h


def main():
    path, out_dir = Path(sys.argv[1]), Path(sys.argv[2])
    out_dir.mkdir(parents=True, exist_ok=True)
    exr = OpenEXR.File(str(path), separate_channels=True)
    header = exr.header()
    channels = exr.channels()

    types = {name: str(c.type()).split(".")[-1] for name, c in channels.items()}
    (out_dir / "channels.json").write_text(json.dumps(types, sort_keys=True))
    for name, c in channels.items():
        (out_dir / f"{name}.f32").write_bytes(c.pixels.astype("<f4").tobytes())

    def layer(name):
        return channels[name].pixels.astype(np.float64)

    height, width = channels["R"].pixels.shape

    # Standard attributes.
    check(header.get("framesPerSecond") == Fraction(24, 1), "framesPerSecond is 24/1")
    chroma = header.get("chromaticities")
    check(
        chroma is not None
        and np.allclose(chroma, [0.64, 0.33, 0.30, 0.60, 0.15, 0.06, 0.3127, 0.3290], atol=1e-6),
        "chromaticities are Rec. 709 with D65",
    )
    for key in ("worldToNDC", "worldToCamera", "screenWindowWidth", "screenWindowCenter"):
        check(key in header, f"header has {key}")
    expect_owner = len(sys.argv) > 3 and sys.argv[3] == "--stamped"
    if not expect_owner:
        check("owner" not in header and "capDate" not in header, "no owner or capDate by default")

    # Cryptomatte metadata.
    key = format(mmh3.hash(b"CryptoObject", 0, signed=False), "08x")[:7]
    prefix = f"cryptomatte/{key}/"
    check(header.get(prefix + "name") == "CryptoObject", f"{prefix}name is CryptoObject")
    check(header.get(prefix + "hash") == "MurmurHash3_32", "hash is MurmurHash3_32")
    check(header.get(prefix + "conversion") == "uint32_to_float32", "conversion is uint32_to_float32")
    manifest = json.loads(header[prefix + "manifest"])
    object_names = json.loads(header["snell.objectNames"])
    check(
        sorted(manifest) == sorted(set(object_names) | {"water"}),
        f"the manifest names every object and the water: {sorted(manifest)}",
    )
    for name, hex_id in manifest.items():
        check(int(hex_id, 16) == cryptomatte_id_bits(name), f"manifest id of {name!r} is its MurmurHash3")

    index = layer("IndexOB.X")
    water = layer("WaterMatte.X")
    check(set(np.unique(water)) <= {0.0, 1.0}, "the water matte is 0/1")
    check(np.all(index == np.round(index)) and index.min() >= 0, "IndexOB holds whole numbers")
    check(index.max() <= len(object_names), "every IndexOB has a name")

    # Decode a matte for every name from the ranks, as a compositor's Cryptomatte node does.
    ranks = [
        (channels["CryptoObject00.R"].pixels, channels["CryptoObject00.G"].pixels),
        (channels["CryptoObject00.B"].pixels, channels["CryptoObject00.A"].pixels),
    ]

    def matte(name):
        bits = np.uint32(cryptomatte_id_bits(name))
        total = np.zeros((height, width))
        for ids, coverage in ranks:
            total += np.where(ids.view(np.uint32) == bits, coverage.astype(np.float64), 0.0)
        return total

    # The frame is anti-aliased (README, "Anti-aliasing"): the Cryptomatte counts each pixel's
    # samples, while IndexOB and the water matte are the pixel centre's. So a pixel's coverage is
    # exactly its centre's only inside a region: where the 3 x 3 pixels around it agree.
    def interior(mask):
        padded = np.pad(mask, 1, mode="edge")
        inside = np.ones_like(mask)
        for dy in (0, 1, 2):
            for dx in (0, 1, 2):
                inside &= padded[dy:dy + height, dx:dx + width]
        return inside

    water_matte = matte("water")
    mattes = {name: matte(name) for name in object_names}
    total = water_matte + sum(mattes.values())
    check(np.all(total <= 1 + 1e-6), "the shares of a pixel sum to at most 1")
    # Only two ranks are written: where the water's share is missing from a water pixel, three or
    # more IDs met there and the two written hold other IDs (the water's share F is the smallest).
    water_bits = np.uint32(cryptomatte_id_bits("water"))
    dropped = (water == 1) & (water_matte == 0)
    for ids, coverage in ranks:
        check(
            np.all((coverage[dropped] > 0) & (ids[dropped].view(np.uint32) != water_bits)),
            f"the water's Cryptomatte covers the water matte but where two other IDs outrank it ({dropped.sum()} px)",
        )
    check(np.all(water_matte[interior(water == 0)] == 0), "no water share inside dry regions")
    seen_objects = 0
    for k, name in enumerate(object_names, start=1):
        m = mattes[name]
        own = index == k
        if not own.any():
            continue
        seen_objects += 1
        check(np.all(m[interior(~own)] == 0), f"{name!r}: no matte inside regions where IndexOB is not {k}")
        direct = interior(own & (water == 0))
        check(np.all(m[direct] == 1), f"{name!r}: matte 1 inside regions seen directly")
        through = interior(own & (water == 1))
        if through.any():
            shares = m[through] + water_matte[through]
            check(
                np.all((m[through] > 0) & (np.abs(shares - 1) < 1e-6)),
                f"{name!r}: through water the object and the water share the pixel ({through.sum()} px)",
            )
        check(np.mean(m[own] > 0) > 0.99, f"{name!r}: a matte where IndexOB is {k}")
    check(seen_objects >= 3, f"{seen_objects} objects are seen")
    empty = (index == 0) & (water == 0)
    check(empty.any(), "some pixels see sky")
    for ids, coverage in ranks:
        inside = interior(empty)
        check(np.all(coverage[inside] == 0) and np.all(ids[inside] == 0), "sky has no Cryptomatte ID")

    # Sky and what is not seen.
    check(np.all(layer("Z")[empty] == SKY_DEPTH_M), "sky Z is 1e10")
    check(np.all(layer("ApparentDepth.Z")[index == 0] == SKY_DEPTH_M), "apparent depth 1e10 where nothing is seen")
    for name in ("Motion.X", "Motion.Y"):
        motion = layer(name)
        check(np.all(np.isfinite(motion)), f"{name} is finite")
        check(np.all(motion[index == 0] == 0), f"{name} is 0 where nothing is seen")
        check(np.any(motion[index != 0] != 0), f"{name} moves where something is seen (the pool's waves)")
    for axis in "XYZ":
        check(np.all(layer(f"P.{axis}")[index == 0] == 0), f"P.{axis} is 0 where nothing is seen")
    for channel in ("FlagConvergence.X", "FlagBoundary.X", "FlagPopping.X", "FlagExtrapolated.X"):
        values = layer(channel)
        check(set(np.unique(values)) <= {0.0, 1.0}, f"{channel} is 0/1")
        check(np.all(values[water == 0] == 0), f"{channel} only under water")

    # The effects sum to the beauty; each lives where it should.
    for c in "RGB":
        total = layer(f"Direct.{c}") + layer(f"Refraction.{c}") + layer(f"SkyReflection.{c}")
        beauty = layer(c)
        check(np.all(np.abs(total - beauty) <= 1e-6 * np.maximum(1.0, np.abs(beauty))), f"effects sum to {c}")
        check(np.all(layer(f"Direct.{c}")[water == 1] == 0), f"Direct.{c} is 0 on water")
        check(np.all(layer(f"Refraction.{c}")[water == 0] == 0), f"Refraction.{c} is 0 off water")

    # Z is the depth along the view axis, and worldToNDC projects each point seen directly to its
    # pixel. The matrices are Imath's: row vectors, p' = p M.
    direct = (index > 0) & (water == 0)
    check(direct.sum() > 100, f"{direct.sum()} pixels see an object directly")
    p = np.stack([layer("P.X"), layer("P.Y"), layer("P.Z"), np.ones((height, width))], axis=-1)[direct]
    camera = p @ np.asarray(header["worldToCamera"], dtype=np.float64)
    z = layer("Z")[direct]
    check(np.max(np.abs(camera[:, 2] - z)) < 1e-3, "Z is the camera-space depth of P (worldToCamera, +Z forward)")
    ndc = p @ np.asarray(header["worldToNDC"], dtype=np.float64)
    ndc = ndc[:, :2] / ndc[:, 3:4]
    ys, xs = np.nonzero(direct)
    error_px = np.hypot(ndc[:, 0] * width - (xs + 0.5), ndc[:, 1] * height - (ys + 0.5))
    check(np.max(error_px) < 0.02, f"worldToNDC puts P at its pixel (max {np.max(error_px):.4f} px)")
    window = float(header["screenWindowWidth"])
    check(np.all(np.asarray(header["screenWindowCenter"]) == 0), "screenWindowCenter is 0, 0")
    along = camera[:, 0] / camera[:, 2] / window + 0.5
    check(np.max(np.abs(along - ndc[:, 0])) < 1e-4, "worldToNDC agrees with screenWindowWidth")
    print("all checks passed")


if __name__ == "__main__":
    main()
