#!/usr/bin/env python3
"""Whether two screenshots are the same picture up to rounding: decodes two 8-bit RGB or RGBA
PNGs (no library: zlib and the PNG filters) and fails when more than MAX_PERCENT of the
pixels differ. Usage: png_close.py A.png B.png [MAX_PERCENT, default 0.1]."""
import sys, zlib, struct

def decode(path):
    data = open(path, 'rb').read()
    assert data[:8] == b'\x89PNG\r\n\x1a\n'
    pos, idat = 8, b''
    while pos < len(data):
        n, kind = struct.unpack('>I4s', data[pos:pos + 8])
        body = data[pos + 8:pos + 8 + n]
        if kind == b'IHDR':
            w, h, depth, ctype = struct.unpack('>IIBB', body[:10])
        elif kind == b'IDAT':
            idat += body
        pos += 12 + n
    bpp = {2: 3, 6: 4}[ctype]
    raw = zlib.decompress(idat)
    stride = w * bpp
    rows, prev = [], bytearray(stride)
    for y in range(h):
        f = raw[y * (stride + 1)]
        line = bytearray(raw[y * (stride + 1) + 1:(y + 1) * (stride + 1)])
        for x in range(stride):
            a = line[x - bpp] if x >= bpp else 0
            b = prev[x]
            c = prev[x - bpp] if x >= bpp else 0
            if f == 1: line[x] = (line[x] + a) & 255
            elif f == 2: line[x] = (line[x] + b) & 255
            elif f == 3: line[x] = (line[x] + (a + b) // 2) & 255
            elif f == 4:
                p = a + b - c; pa, pb, pc = abs(p - a), abs(p - b), abs(p - c)
                line[x] = (line[x] + (a if pa <= pb and pa <= pc else b if pb <= pc else c)) & 255
        rows.append(bytes(line)); prev = line
    return w, h, bpp, rows


def main():
    limit = float(sys.argv[3]) if len(sys.argv) > 3 else 0.1
    wa, ha, ba, ra = decode(sys.argv[1])
    wb, hb, bb, rb = decode(sys.argv[2])
    if (wa, ha) != (wb, hb):
        sys.exit(f"{sys.argv[1]} is {wa}x{ha}, {sys.argv[2]} {wb}x{hb}")
    diff, worst = 0, 0
    for la, lb in zip(ra, rb):
        for x, y in zip(range(0, len(la), ba), range(0, len(lb), bb)):
            d = max(abs(la[x + k] - lb[y + k]) for k in range(3))
            if d:
                diff += 1
                worst = max(worst, d)
    percent = 100 * diff / (wa * ha)
    print(f"{diff} of {wa * ha} pixels differ ({percent:.3f} %), largest channel difference {worst}")
    if percent > limit:
        sys.exit(f"more than {limit} % of the pixels differ")

main()
