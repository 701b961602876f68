#!/usr/bin/env python3
"""Cross-sections of one side of a ridge (slope 25 degrees, band 1500 m) with each slope falloff,
drawn as a PNG with the standard library only (no plotting package needed).

Usage: scripts/plot_falloff.py [OUT.png]   (default docs/falloff_profiles.png)

Red: "foot" (1 - u^2)^2, the default; blue: "sigmoid" 1 - 3u^2 + 2u^3; black: "none" (constant
slope to the band edge, then flat: the crease). Grey: the band edge (u = 1) and the crest height.
x: distance from the curve, 0 to 2000 m; y: height below the crest, 0 to 750 m (1 px = 2.5 m
vertically, 3.33 m horizontally; the vertical scale is exaggerated 1.33 times).
"""
import math
import struct
import sys
import zlib

W, H, PAD = 600, 300, 20
WIDTH_M, SLOPE_DEG, X_MAX, Y_MAX = 1500.0, 25.0, 2000.0, 750.0
PROFILES = {
    "foot": (lambda u: (1 - u * u) ** 2, (220, 40, 30)),
    "sigmoid": (lambda u: 1 - 3 * u * u + 2 * u ** 3, (30, 80, 220)),
    "none": (lambda u: 1.0, (0, 0, 0)),
}


def heights(profile, steps=4000):
    """Height below the crest along the distance, integrating the slope."""
    tan = math.tan(math.radians(SLOPE_DEG))
    out, z = [], 0.0
    dx = X_MAX / steps
    for k in range(steps + 1):
        d = k * dx
        out.append((d, z))
        u = min(d / WIDTH_M, 1.0)
        z += tan * (profile(u) if d < WIDTH_M else 0.0) * dx
    return out


def main():
    path = sys.argv[1] if len(sys.argv) > 1 else "docs/falloff_profiles.png"
    img = [[(255, 255, 255)] * W for _ in range(H)]

    def px(d, z):
        return (PAD + int(d / X_MAX * (W - 2 * PAD)), PAD + int(z / Y_MAX * (H - 2 * PAD)))

    def dot(x, y, c, r=1):
        for yy in range(y - r, y + r + 1):
            for xx in range(x - r, x + r + 1):
                if 0 <= xx < W and 0 <= yy < H:
                    img[yy][xx] = c

    grey = (170, 170, 170)
    for z in range(0, int(Y_MAX) + 1, 2):
        dot(*px(WIDTH_M, z), grey, 0)
    for d in range(0, int(X_MAX) + 1, 2):
        dot(*px(d, 0), grey, 0)
    for name in ["none", "sigmoid", "foot"]:
        profile, colour = PROFILES[name]
        for d, z in heights(profile):
            dot(*px(d, z), colour)
    raw = b"".join(b"\x00" + bytes(v for p in row for v in p) for row in img)
    chunk = lambda tag, data: (struct.pack(">I", len(data)) + tag + data
                               + struct.pack(">I", zlib.crc32(tag + data) & 0xFFFFFFFF))
    png = (b"\x89PNG\r\n\x1a\n" + chunk(b"IHDR", struct.pack(">IIBBBBB", W, H, 8, 2, 0, 0, 0))
           + chunk(b"IDAT", zlib.compress(raw, 9)) + chunk(b"IEND", b""))
    with open(path, "wb") as f:
        f.write(png)


if __name__ == "__main__":
    main()
