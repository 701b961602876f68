#!/usr/bin/env python3
"""Converts a binary greyscale PGM (P5, 8 bit; e.g. the hillshades of
`cargo run --release -p terrasketch-tools --bin look -- laplacian SKETCH N OUT.pgm`) to PNG,
optionally cropped, with the standard library only.

Usage: scripts/pgm2png.py IN.pgm OUT.png [X Y W H]
"""
import struct
import sys
import zlib


def main():
    data = open(sys.argv[1], "rb").read()
    parts = data.split(maxsplit=4)
    assert parts[0] == b"P5" and parts[3] == b"255", "8-bit binary PGM expected"
    w, h = int(parts[1]), int(parts[2])
    pixels = data[len(data) - w * h:]
    x0, y0, cw, ch = (int(v) for v in sys.argv[3:7]) if len(sys.argv) >= 7 else (0, 0, w, h)
    rows = [pixels[(y0 + j) * w + x0:(y0 + j) * w + x0 + cw] for j in range(ch)]
    raw = b"".join(b"\x00" + r for r in rows)
    chunk = lambda tag, d: (struct.pack(">I", len(d)) + tag + d
                            + struct.pack(">I", zlib.crc32(tag + d) & 0xFFFFFFFF))
    png = (b"\x89PNG\r\n\x1a\n" + chunk(b"IHDR", struct.pack(">IIBBBBB", cw, ch, 8, 0, 0, 0, 0))
           + chunk(b"IDAT", zlib.compress(raw, 9)) + chunk(b"IEND", b""))
    open(sys.argv[2], "wb").write(png)


if __name__ == "__main__":
    main()
