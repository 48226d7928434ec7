#!/usr/bin/env python3
"""Plot L2 error against h from convergence CSVs (peridot converge, or the `paper` studies).

usage: tools/plot_convergence.py OUT.png CSV [CSV ...]
Each CSV needs the columns h, error_u and error_theta. Uses Debian's python3-matplotlib.
"""
import csv
import math
import os
import sys

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt


def main(argv):
    if len(argv) < 3:
        print(__doc__, file=sys.stderr)
        return 2
    out, files = argv[1], argv[2:]
    fig, axes = plt.subplots(1, 2, figsize=(11, 4.5))
    for f in files:
        try:
            rows = list(csv.DictReader(open(f)))
            h = [float(r["h"]) for r in rows]
            eu = [float(r["error_u"]) for r in rows]
            et = [float(r["error_theta"]) for r in rows]
        except (OSError, KeyError, ValueError) as e:
            print(f"error: {f}: {e}", file=sys.stderr)
            return 1
        label = os.path.splitext(os.path.basename(f))[0]
        for ax, e in zip(axes, (eu, et)):
            ax.loglog(h, e, "o-", label=label)
    for ax, name in zip(axes, ("u", "theta")):
        hmin, hmax = ax.get_xlim()
        for p, style in ((1, ":"), (2, "--")):
            y0 = ax.get_ylim()[0] * 3
            ax.loglog([hmin, hmax], [y0, y0 * (hmax / hmin) ** p], "k" + style, lw=0.8, label=f"order {p}")
        ax.set_xlabel("h [m]")
        ax.set_ylabel(f"L2 error of {name}")
        ax.grid(True, which="both", alpha=0.3)
    axes[0].legend(fontsize=7)
    fig.tight_layout()
    fig.savefig(out, dpi=120)
    print(f"wrote {out}")
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv))
