"""Identify an ARX model of a recorded flexible robot arm and validate it.

Run:  python examples/identify_recorded.py [record.csv]

Default record: the DaISy 96-009 flexible robot arm (reaction torque -> arm acceleration),
read from ``../shared/data/real/robot_arm.csv`` when present; otherwise a simulated
manipulator record stands in.  The sample time is not given by DaISy; 0.01 s is assumed.

Least squares is the exact optimum of the one-step cost; HBCSD searches the same cost with a
stability penalty, which matters here: least squares is unstable for several orders of this
record (see the data README).
"""

from __future__ import annotations

import sys
from pathlib import Path

import flexid

DEFAULT = Path(__file__).resolve().parents[2] / "shared" / "data" / "real" / "robot_arm.csv"


def main(path: str | None = None) -> None:
    record = Path(path) if path else DEFAULT
    if record.exists():
        data = flexid.load(record, inputs=["u"], outputs=["y"], dt=0.01)
        name = record.stem
        print(f"record {record.name}: {data.n_samples} samples")
    else:
        print(f"{record} not found; using a simulated manipulator record instead")
        data = flexid.generate("manipulator", preset="paper-manipulator", seed=0)
        name = "simulated-manipulator"

    ls = flexid.identify(data, na=8, nb=8, nk=1, optimiser="ls")
    print(ls.summary())
    print()
    hb = flexid.identify(data, na=8, nb=8, nk=1, optimiser="hbcsd", budget=30_000, seed=1)
    print(hb.summary())
    try:
        from flexid.report.plots import identification_figures

        paths = identification_figures(hb, "flexid-figures", prefix=f"{name}-")
        print(f"\nfigures: {', '.join(p.name for p in paths)} in flexid-figures/")
    except ImportError:
        print("\n(install the 'plot' extra for figures)")


if __name__ == "__main__":
    main(*sys.argv[1:2])
