#!/usr/bin/env python3
"""The Kalthoff-Winkler crack, measured the same way in Peridot's and CabanaPD's output.

usage: kw_crack.py OUTPUT [--threshold 0.35] [--margin 0.002]

OUTPUT is a Peridot VTU (raw appended, as `peridot run` writes) or a CabanaPD particles_N.h5
(read with h5dump from Debian's hdf5-tools). Both decks put the plate's centre at the origin and
the notch tips at (0, +-0.025) m, the notches running along +x from the struck edge.

For each notch it keeps the points with damage >= threshold beyond the tip (|y| > 0.025 + margin,
x > -margin; the lower notch mirrored), through the whole thickness, and fits their principal
axis (total least squares: the crack is steep, so y-on-x regression would be biased). It prints
the angle of that axis to the notch (+x) [deg], how far the crack reaches in |y| [m], the
points, and the mean point damage of the whole body.
"""
import argparse
import math
import os
import re
import struct
import subprocess
import sys
import tempfile
from array import array


def read_vtu(path):
    with open(path, "rb") as f:
        data = f.read()
    start = data.index(b'<AppendedData encoding="raw">')
    header = data[:start].decode("ascii", "replace")
    if 'header_type="UInt64"' not in header:
        sys.exit(f"{path}: expected a VTU with header_type UInt64")
    base = data.index(b"_", start) + 1
    fields = {}
    for m in re.finditer(r'<DataArray type="Float64" Name="([^"]+)"(?: NumberOfComponents="(\d+)")? format="appended" offset="(\d+)"', header):
        name, comps, offset = m.group(1), int(m.group(2) or 1), int(m.group(3))
        (nbytes,) = struct.unpack_from("<Q", data, base + offset)
        a = array("d")
        a.frombytes(data[base + offset + 8: base + offset + 8 + nbytes])
        fields[name] = (a, comps)
    return fields["Points"][0], fields["damage"][0]


def read_h5(path):
    def dataset(name):
        with tempfile.NamedTemporaryFile(suffix=".bin") as tmp:
            subprocess.run(["h5dump", "-d", "/" + name, "-b", "LE", "-o", tmp.name, path], check=True, stdout=subprocess.DEVNULL)
            a = array("d")
            a.frombytes(open(tmp.name, "rb").read())
            return a
    try:
        return dataset("reference_positions"), dataset("damage")
    except FileNotFoundError:
        sys.exit("h5dump not found: apt-get install hdf5-tools")


def principal_angle(pts):
    n = len(pts)
    mx = sum(p[0] for p in pts) / n
    my = sum(p[1] for p in pts) / n
    sxx = sum((p[0] - mx) ** 2 for p in pts) / n
    syy = sum((p[1] - my) ** 2 for p in pts) / n
    sxy = sum((p[0] - mx) * (p[1] - my) for p in pts) / n
    a = math.degrees(0.5 * math.atan2(2 * sxy, sxx - syy))
    return a + 180 if a < 0 else a


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("output")
    ap.add_argument("--threshold", type=float, default=0.35)
    ap.add_argument("--margin", type=float, default=0.002, help="[m]; default: the decks' horizon")
    a = ap.parse_args()
    x, damage = read_vtu(a.output) if a.output.endswith(".vtu") else read_h5(a.output)
    n = len(damage)
    if len(x) != 3 * n:
        sys.exit(f"{a.output}: {len(x)} coordinates for {n} points")
    print(f"{os.path.basename(a.output)}: {n} points, mean point damage {sum(damage) / n:.5f}")
    for label, sign in (("upper", 1), ("lower", -1)):
        pts = [(x[3 * i], sign * x[3 * i + 1]) for i in range(n)
               if damage[i] >= a.threshold and sign * x[3 * i + 1] > 0.025 + a.margin and x[3 * i] > -a.margin]
        if len(pts) < 3:
            print(f"  {label} notch: {len(pts)} cracked points beyond the tip, no angle")
            continue
        reach = max(p[1] for p in pts)
        print(f"  {label} notch: {principal_angle(pts):.1f} deg to the notch, reaches |y| = {reach:.4f} m, {len(pts)} points")


if __name__ == "__main__":
    main()
