"""The Cryptomatte layer of render_passes against the CLI's EXR and the spec's rules."""

import json
import struct

import numpy as np

import nephele
from conftest import read_exr, same_bits


def murmur3_32(data: bytes, seed: int = 0) -> int:
    """MurmurHash3_x86_32, written here from the reference (not nephele's)."""
    c1, c2, mask = 0xCC9E2D51, 0x1B873593, 0xFFFFFFFF
    h = seed
    n = len(data) // 4
    for i in range(n):
        (k,) = struct.unpack_from("<I", data, 4 * i)
        k = (k * c1) & mask
        k = ((k << 15) | (k >> 17)) & mask
        k = (k * c2) & mask
        h ^= k
        h = ((h << 13) | (h >> 19)) & mask
        h = (h * 5 + 0xE6546B64) & mask
    tail = data[4 * n:]
    k = 0
    for i, byte in enumerate(tail):
        k |= byte << (8 * i)
    if tail:
        k = (k * c1) & mask
        k = ((k << 15) | (k >> 17)) & mask
        k = (k * c2) & mask
        h ^= k
    h ^= len(data)
    h ^= h >> 16
    h = (h * 0x85EBCA6B) & mask
    h ^= h >> 13
    h = (h * 0xC2B2AE35) & mask
    h ^= h >> 16
    return h


def spec_id(name: str) -> np.float32:
    """The spec's id of a name: its hash's bits as a float, exponent clamped to [1, 254]."""
    h = murmur3_32(name.encode())
    exponent = min(max((h >> 23) & 0xFF, 1), 254)
    bits = (h & 0x8000_0000) | (exponent << 23) | (h & 0x7FFFFF)
    return np.array([bits], dtype=np.uint32).view(np.float32)[0]


def text(value):
    return value.decode() if isinstance(value, bytes) else str(value)


def test_mattes_equal_the_cli_cryptomatte(tmp_path, tiny_scene, cli):
    out = tmp_path / "cli"
    cli("render", tiny_scene, "--output", out, "--passes", "--frames", "3")
    shot = nephele.Scene.load(tiny_scene).shot(passes=True, frames=[3])
    layers = shot.render_passes(3)
    m = layers["mattes"]
    channels, header = read_exr(out / "tiny_0003.exr")
    layer, key = m["layer"], m["key"]
    assert layer == "CryptoObject" and key == f"{murmur3_32(layer.encode()):08x}"[:7]
    assert text(header[f"cryptomatte/{key}/name"]) == layer
    assert text(header[f"cryptomatte/{key}/hash"]) == "MurmurHash3_32"
    manifest = json.loads(text(header[f"cryptomatte/{key}/manifest"]))
    assert m["manifest"] == manifest and sorted(m["names"]) == sorted(manifest)
    # Each id is the spec's hash of its name (computed here), and is what the manifest says.
    for name, id_ in zip(m["names"], m["ids"]):
        assert np.float32(id_).view(np.uint32) == spec_id(name).view(np.uint32), name
        assert manifest[name] == f"{int(spec_id(name).view(np.uint32)):08x}"
    # The ranks, bit for bit: each of the 3 RGBA channel sets holds two (id, coverage) ranks.
    h, w = 27, 48
    for a in ("index", "id", "coverage"):
        assert m[a].shape == (h, w, 6)
    assert m["index"].dtype == np.int32 and m["id"].dtype == m["coverage"].dtype == np.float32
    for s in range(3):
        ch = {c: channels[f"{layer}{s:02d}.{c}"] for c in "RGBA"}
        assert same_bits(m["id"][..., 2 * s], ch["R"]), s
        assert same_bits(m["coverage"][..., 2 * s], ch["G"]), s
        assert same_bits(m["id"][..., 2 * s + 1], ch["B"]), s
        assert same_bits(m["coverage"][..., 2 * s + 1], ch["A"]), s
    # index names the id's matte; an empty rank is index -1, id 0 and coverage 0.
    ids = np.array(m["ids"], dtype=np.float32)
    named = m["index"] >= 0
    assert same_bits(m["id"][named], ids[m["index"][named]])
    assert (m["id"][~named] == 0).all() and (m["coverage"][~named] == 0).all()
    # Ranked by coverage, and together they are the pixel's alpha (the spec's coverage).
    cov = m["coverage"]
    assert (np.diff(cov, axis=-1) <= 0).all()
    alpha = layers["rgba"][..., 3]
    assert named.any() and len(m["names"]) >= 2
    np.testing.assert_allclose(cov.sum(-1), alpha, atol=2e-3)


def test_matte_coverage_picks_a_piece(tiny_scene):
    shot = nephele.Scene.load(tiny_scene).shot(passes=True)
    m = shot.render_passes(3)["mattes"]
    total = np.zeros(m["coverage"].shape[:2], dtype=np.float32)
    for name in m["names"]:
        piece = nephele.matte_coverage(m, name)
        assert piece.shape == total.shape and (piece >= 0).all()
        total += piece
    np.testing.assert_allclose(total, m["coverage"].sum(-1), atol=1e-6)
    seen = [name for name in m["names"] if nephele.matte_coverage(m, name).max() > 0]
    assert seen, "some piece is visible"
    try:
        nephele.matte_coverage(m, "no such piece")
    except KeyError as e:
        assert "no such piece" in str(e)
    else:
        raise AssertionError("an unknown matte name raises KeyError")
