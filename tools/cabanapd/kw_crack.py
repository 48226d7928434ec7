#!/usr/bin/env python3
"""The Kalthoff-Winkler crack, measured the same way in Peridot's and CabanaPD's output.

usage: kw_crack.py OUTPUT [OUTPUT ...] [--threshold 0.35] [--margin 0.002]

OUTPUT is a Peridot VTU (raw appended, as `peridot run` writes) or a CabanaPD particles_N.h5
(read with h5dump from Debian's hdf5-tools). Both decks put the plate's centre at the origin and
the notch tips at (0, +-0.025) m, the notches running along +x from the struck edge.

For each notch it keeps the points with damage >= threshold beyond the tip (|y| > 0.025 + margin,
x > -margin; the lower notch mirrored), through the whole thickness, and fits their principal
axis (total least squares: the crack is steep, so y-on-x regression would be biased). It prints
the angle of that axis to the notch (+x) [deg], how far the crack reaches in |y| [m], the
points, and the mean point damage of the whole body. It also prints the crack's length: the
distance from the notch tip to its farthest cracked point.

Given several outputs of one run (Peridot's VTU series, CabanaPD's particles_N.h5), it takes each
one's time from the run's .pvd (Peridot) or the particles_N.xmf beside it (CabanaPD) and ends with
the crack speed: the length's growth over time while the crack runs (from the first output where
it is longer than 2 mm to the first where it has 95 % of its final length), a least-squares slope.
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


def output_time(path):
    """The simulated time [s] of one output, from the files its code writes beside it."""
    folder, name = os.path.split(path)
    if path.endswith(".vtu"):
        for pvd in os.listdir(folder or "."):
            if pvd.endswith(".pvd"):
                m = re.search(r'timestep="([^"]+)"[^>]*file="%s"' % re.escape(name), open(os.path.join(folder, pvd)).read())
                if m:
                    return float(m.group(1))
    else:
        xmf = os.path.splitext(path)[0] + ".xmf"
        if os.path.exists(xmf):
            m = re.search(r'<Time Value="([^"]+)"', open(xmf).read())
            if m:
                return float(m.group(1))
    return math.nan


def speed(times, lengths):
    """Least-squares slope of length over time while the crack runs, or NaN."""
    final = max(lengths)
    run = [(t, l) for t, l in zip(times, lengths) if l > 0.002]
    if not run:
        return math.nan
    end = next(i for i, (t, l) in enumerate(run) if l >= 0.95 * final)
    run = run[:end + 1]
    if len(run) < 2:
        return math.nan
    mt = sum(t for t, _ in run) / len(run)
    ml = sum(l for _, l in run) / len(run)
    return sum((t - mt) * (l - ml) for t, l in run) / sum((t - mt) ** 2 for t, _ in run)


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
    ap.add_argument("output", nargs="+")
    ap.add_argument("--threshold", type=float, default=0.35)
    ap.add_argument("--margin", type=float, default=0.002, help="[m]; default: the decks' horizon")
    a = ap.parse_args()
    series = {"upper": [], "lower": []}
    times = []
    for path in a.output:
        x, damage = read_vtu(path) if path.endswith(".vtu") else read_h5(path)
        n = len(damage)
        if len(x) != 3 * n:
            sys.exit(f"{path}: {len(x)} coordinates for {n} points")
        t = output_time(path)
        times.append(t)
        print(f"{os.path.basename(path)}: t = {t * 1e6:.2f} us, {n} points, mean point damage {sum(damage) / n:.5f}")
        for label, sign in (("upper", 1), ("lower", -1)):
            pts = [(x[3 * i], sign * x[3 * i + 1]) for i in range(n)
                   if damage[i] >= a.threshold and sign * x[3 * i + 1] > 0.025 + a.margin and x[3 * i] > -a.margin]
            length = max((math.hypot(p[0], p[1] - 0.025) for p in pts), default=0.0)
            series[label].append(length)
            if len(pts) < 3:
                print(f"  {label} notch: {len(pts)} cracked points beyond the tip, no angle")
                continue
            reach = max(p[1] for p in pts)
            print(f"  {label} notch: {principal_angle(pts):.1f} deg to the notch, reaches |y| = {reach:.4f} m, "
                  f"length {length:.4f} m, {len(pts)} points")
    if len(a.output) > 1:
        for label, lengths in series.items():
            v = speed(times, lengths)
            print(f"{label} crack: speed {v:.0f} m/s while it runs (lengths {', '.join(f'{l * 1e3:.1f}' for l in lengths)} mm)")


if __name__ == "__main__":
    main()
