#!/usr/bin/env python3
"""The page codec survey beside `farfield-server bench codecs`: how general
compressors without a pure-Rust encoder (zstd, LZMA, LZ4) would store a
built file's page bodies, plain, split into byte planes ("shuf"), and, for
spheres, split into fields with deltas ("fields"). Sizes only; the Rust
bench times what the format can use.
Usage: python3 benches/page_codecs.py FILE...  (pip install zstandard lz4)"""
import lzma
import struct
import sys
import zlib

import lz4.block
import zstandard

FIXED = 136


def pages(path):
    data = open(path, "rb").read()
    kind, attrs, cluster = data[16], data[17], data[18]
    node_bytes, levels, count = struct.unpack_from("<III", data, 20)
    inputs = struct.unpack_from("<Q", data, 48)[0]
    out = []
    framing = len(data)
    for i in range(count):
        off, length, nodes = struct.unpack_from("<QII", data, FIXED + 40 * i)
        page = data[off : off + length]
        codec, decoded_len = page[32], struct.unpack_from("<I", page, 36)[0]
        body = page[40:-4]
        framing -= len(body)
        if codec == 1:
            planes = zlib.decompress(body, -15)
            records = unshuffle(planes[: nodes * node_bytes], node_bytes)
            body = records + planes[nodes * node_bytes :]
        assert len(body) == decoded_len
        out.append((nodes, body))
    return kind, attrs, node_bytes, inputs, framing, out


def unshuffle(planes, nb):
    n = len(planes) // nb
    out = bytearray(len(planes))
    for b in range(nb):
        out[b::nb] = planes[b * n : (b + 1) * n]
    return bytes(out)


def shuffle(records, nb):
    n = len(records) // nb
    return b"".join(records[b::nb][:n] for b in range(nb))


def fields(records, nb, attrs):
    normals, color = attrs & 2, attrs & 1
    n = len(records) // nb
    pos_lo, pos_hi, kids, nfa, nu, nv, cone, r, g, b = ([] for _ in range(10))
    prev = [0, 0, 0, 0, 0, 0]
    for i in range(n):
        v = int.from_bytes(records[i * nb : (i + 1) * nb], "little")
        p = v & 0x1FFF
        pos_lo.append(p & 0xFF)
        pos_hi.append(p >> 8)
        kids.append((v >> 13) & 3)
        at = 15
        if normals:
            nc = (v >> at) & 0x3FFF
            at += 14
            f, rest = divmod(nc, 2704)
            u, w = divmod(rest, 52)
            nfa.append(f)
            nu.append((u - prev[0]) & 0xFF)
            nv.append((w - prev[1]) & 0xFF)
            prev[0], prev[1] = u, w
            cone.append((v >> at) & 3)
            at += 2
        if color:
            c = (v >> at) & 0xFFFF
            rr, gg, bb = c >> 11, (c >> 5) & 63, c & 31
            r.append((rr - prev[2]) & 0xFF)
            g.append((gg - prev[3]) & 0xFF)
            b.append((bb - prev[4]) & 0xFF)
            prev[2], prev[3], prev[4] = rr, gg, bb

    def pack2(xs):
        out = bytearray((len(xs) + 3) // 4)
        for i, x in enumerate(xs):
            out[i // 4] |= x << (2 * (i % 4))
        return bytes(out)

    return b"".join(
        [bytes(pos_lo), bytes(pos_hi), pack2(kids), bytes(nfa), bytes(nu), bytes(nv), pack2(cone), bytes(r), bytes(g), bytes(b)]
    )


CODECS = {
    "deflate6": lambda b: len(zlib.compress(b, 6)) - 6,
    "deflate9": lambda b: len(zlib.compress(b, 9)) - 6,
    "zstd3": lambda b: len(zstandard.ZstdCompressor(level=3).compress(b)),
    "zstd19": lambda b: len(zstandard.ZstdCompressor(level=19).compress(b)),
    "lzma": lambda b: len(lzma.compress(b, format=lzma.FORMAT_RAW, filters=[{"id": lzma.FILTER_LZMA2, "preset": 9}])),
    "lz4": lambda b: len(lz4.block.compress(b, store_size=False)),
}


def main():
    for path in sys.argv[1:]:
        kind, attrs, nb, inputs, framing, ps = pages(path)
        raw = sum(len(b) for _, b in ps)
        print(f"{path}: kind {kind} attrs {attrs} record {nb} B, {len(ps)} pages, {raw} B decoded, {inputs} inputs, {(framing + raw)/max(inputs,1):.2f} B/input uncompressed")
        transforms = {"plain": lambda n, b: b, "shuf": lambda n, b: shuffle(b[: n * nb], nb) + b[n * nb :]}
        if kind == 1:
            transforms["fields"] = lambda n, b: fields(b[: n * nb], nb, attrs)
        for tname, t in transforms.items():
            bodies = [t(n, b) for n, b in ps]
            row = []
            for cname, c in CODECS.items():
                size = sum(min(c(b), len(b)) for b in bodies)
                file = framing + size
                row.append(f"{cname} {raw/size:.2f}x {file/max(inputs,1):.2f}")
            print(f"  {tname:7}", " | ".join(row))


main()
