"""Minimal OpenEXR reader/writer (numpy only; no Blender needed).

Writes single-part scanline files with FLOAT channels, ZIPS compression
(zlib, one scanline per block) or none. Reads single-part scanline files with
HALF/FLOAT channels and NONE, ZIPS or ZIP compression: what this writer and
Blender's OPEN_EXR / OPEN_EXR_MULTILAYER outputs (codec NONE or ZIP) produce.
Written from the OpenEXR file-layout documentation.
"""
import struct
import zlib

import numpy as np

_MAGIC = 20000630
_PIXEL_TYPES = {0: np.uint32, 1: np.float16, 2: np.float32}
_NONE, _ZIPS, _ZIP = 0, 2, 3
_LINES_PER_BLOCK = {_NONE: 1, _ZIPS: 1, _ZIP: 16}


def _attr(name, kind, payload):
    return name.encode() + b"\0" + kind.encode() + b"\0" + struct.pack("<i", len(payload)) + payload


def _predict_and_interleave(raw):
    # The zlib codecs store the bytes split into even and odd positions, then
    # as differences of successive bytes (+128).
    b = np.frombuffer(raw, dtype=np.uint8)
    t = np.concatenate([b[0::2], b[1::2]]).astype(np.int16)
    d = np.empty_like(t)
    d[0] = t[0]
    d[1:] = (t[1:] - t[:-1] + 128) & 0xFF
    return d.astype(np.uint8).tobytes()


def _undo_predict_and_interleave(data):
    d = np.frombuffer(data, dtype=np.uint8).astype(np.int64)
    d[1:] -= 128
    t = (np.cumsum(d) & 0xFF).astype(np.uint8)
    half = (len(t) + 1) // 2
    out = np.empty_like(t)
    out[0::2] = t[:half]
    out[1::2] = t[half:]
    return out.tobytes()


def write_exr(path, image, channels=None, compress=True):
    """image: H x W (one channel, named 'Y') or H x W x C float array (RGB ->
    'R','G','B'). Row 0 is the top of the image."""
    a = np.asarray(image, dtype=np.float32)
    if a.ndim == 2:
        a = a[:, :, None]
    h, w, c = a.shape
    if channels is None:
        channels = {1: ["Y"], 3: ["R", "G", "B"], 4: ["R", "G", "B", "A"]}[c]
    assert len(channels) == c
    order = sorted(range(c), key=lambda i: channels[i])  # the file stores channels sorted by name
    chlist = b"".join(channels[i].encode() + b"\0" + struct.pack("<iB3xii", 2, 0, 1, 1) for i in order) + b"\0"
    comp = _ZIPS if compress else _NONE
    header = struct.pack("<ii", _MAGIC, 2)
    header += _attr("channels", "chlist", chlist)
    header += _attr("compression", "compression", struct.pack("<B", comp))
    header += _attr("dataWindow", "box2i", struct.pack("<iiii", 0, 0, w - 1, h - 1))
    header += _attr("displayWindow", "box2i", struct.pack("<iiii", 0, 0, w - 1, h - 1))
    header += _attr("lineOrder", "lineOrder", struct.pack("<B", 0))
    header += _attr("pixelAspectRatio", "float", struct.pack("<f", 1.0))
    header += _attr("screenWindowCenter", "v2f", struct.pack("<ff", 0.0, 0.0))
    header += _attr("screenWindowWidth", "float", struct.pack("<f", 1.0))
    header += b"\0"
    blocks = []
    for y in range(h):
        raw = b"".join(np.ascontiguousarray(a[y, :, i]).astype("<f4").tobytes() for i in order)
        if comp == _ZIPS:
            packed = zlib.compress(_predict_and_interleave(raw), 6)
            if len(packed) < len(raw):
                raw = packed
        blocks.append(struct.pack("<ii", y, len(raw)) + raw)
    offset = len(header) + 8 * h
    table = []
    for blk in blocks:
        table.append(struct.pack("<Q", offset))
        offset += len(blk)
    with open(path, "wb") as f:
        f.write(header + b"".join(table) + b"".join(blocks))


def read_exr(path):
    """Returns {channel name: H x W float32 array} (row 0 = top)."""
    with open(path, "rb") as f:
        data = f.read()
    magic, version = struct.unpack_from("<ii", data, 0)
    if magic != _MAGIC:
        raise ValueError(path + ": not an OpenEXR file")
    if version & 0x1200:
        raise ValueError(path + ": tiled or multi-part EXR is not supported")
    pos = 8
    attrs = {}
    while data[pos] != 0:
        end = data.index(b"\0", pos)
        name = data[pos:end].decode()
        pos = end + 1
        end = data.index(b"\0", pos)
        pos = end + 1
        size = struct.unpack_from("<i", data, pos)[0]
        pos += 4
        attrs[name] = data[pos:pos + size]
        pos += size
    pos += 1
    chans = []
    cl = attrs["channels"]
    p = 0
    while cl[p] != 0:
        end = cl.index(b"\0", p)
        name = cl[p:end].decode()
        ptype, _, xs, ys = struct.unpack_from("<iB3xii", cl, end + 1)
        if xs != 1 or ys != 1:
            raise ValueError(path + ": subsampled channels are not supported")
        chans.append((name, ptype))
        p = end + 1 + 16
    comp = attrs["compression"][0]
    if comp not in _LINES_PER_BLOCK:
        raise ValueError(path + ": compression %d is not supported" % comp)
    x0, y0, x1, y1 = struct.unpack("<iiii", attrs["dataWindow"])
    w, h = x1 - x0 + 1, y1 - y0 + 1
    lpb = _LINES_PER_BLOCK[comp]
    nblocks = (h + lpb - 1) // lpb
    offsets = struct.unpack_from("<%dQ" % nblocks, data, pos)
    out = {name: np.zeros((h, w), np.float32) for name, _ in chans}
    for off in offsets:
        y, size = struct.unpack_from("<ii", data, off)
        block = data[off + 8:off + 8 + size]
        lines = min(lpb, y1 - y + 1)
        expected = sum(np.dtype(_PIXEL_TYPES[t]).itemsize for _, t in chans) * w * lines
        if comp != _NONE and size < expected:
            block = _undo_predict_and_interleave(zlib.decompress(block))
        q = 0
        for line in range(lines):
            for name, t in chans:
                dt = np.dtype(_PIXEL_TYPES[t]).newbyteorder("<")
                n = dt.itemsize * w
                out[name][y - y0 + line] = np.frombuffer(block[q:q + n], dtype=dt).astype(np.float32)
                q += n
    return out


def read_rgb(path, prefix=""):
    """H x W x 3 from channels prefix+'R','G','B' (or one 'Y'/'V'/'Z' channel repeated)."""
    ch = read_exr(path)
    if prefix + "R" in ch:
        return np.stack([ch[prefix + "R"], ch[prefix + "G"], ch[prefix + "B"]], axis=2)
    for k in ("Y", "V", "Z"):
        if prefix + k in ch:
            return np.repeat(ch[prefix + k][:, :, None], 3, axis=2)
    raise KeyError("%s: no RGB channels under '%s' (has %s)" % (path, prefix, sorted(ch)))
