"""Print a summary of the corpus cases and draw a few tracks, without learning anything.

python -m bench.learn_corpus.show [--seed N] [--n N] [--real] [--png PATH]
"""

from __future__ import annotations

import argparse
from collections import Counter
from pathlib import Path

import numpy as np

from bench.learn_corpus.case import Case
from bench.learn_corpus.real import real_cases
from bench.learn_corpus.stress import DEV_SEEDS, stress_cases


def _truth_text(case: Case) -> str:
    parts = []
    for p in case.truth:
        if p.kind == "rotation":
            radius = f" r{p.radius_m:.3f}" if p.radius_m is not None else ""
            parts.append(f"R{np.degrees(p.extent):+.0f}d{radius}".replace("+", ""))
        else:
            parts.append(f"T{p.extent:.3f}m")
    return " ".join(parts)


def summary_lines(cases: list[Case]) -> list[str]:
    """One line per case: name, rate (Hz), noise (mm), streams, tags and the truth's primitives."""
    lines = [f"{'case':<44} {'Hz':>6} {'noise mm':>9} {'mk':>3} {'ps':>3} {'wr':>3}  truth | tags"]
    for c in cases:
        lines.append(
            f"{c.name:<44} {c.hz:6.1f} {1000 * c.noise_m:9.2f} {len(c.markers):3d} {len(c.poses):3d} "
            f"{'y' if c.wrist is not None else '-':>3}  {_truth_text(c)} | {','.join(c.tags)}"
        )
    counts = Counter(tag for c in cases for tag in c.tags)
    lines.append(f"{len(cases)} cases; tags: " + ", ".join(f"{tag} {n}" for tag, n in counts.most_common()))
    rates = np.array([c.hz for c in cases])
    noise = np.array([1000 * c.noise_m for c in cases])
    lines.append(
        f"rate {rates.min():.0f}-{rates.max():.0f} Hz (median {np.median(rates):.0f}); "
        f"noise {noise.min():.2f}-{noise.max():.2f} mm (median {np.median(noise):.2f})"
    )
    return lines


def draw(cases: list[Case], path: Path) -> None:
    """A PNG of up to nine cases (one per folder): x, y, z of each stream against time, truth spans shaded."""
    import matplotlib as mpl

    mpl.use("Agg")
    import matplotlib.pyplot as plt

    groups: dict[str, Case] = {}
    for case in cases:
        groups.setdefault(case.name.rsplit("/", 1)[0] if "/" in case.name else case.name, case)
    shown = list(groups.values())[:9]
    fig, axes = plt.subplots(len(shown), 1, figsize=(12, 2.3 * len(shown)), squeeze=False)
    for ax, case in zip(axes[:, 0], shown, strict=True):
        streams = [(n, t, xyz) for n, (t, xyz) in case.markers.items()]
        streams += [(n, t, xyz) for n, (t, xyz, _) in case.poses.items()]
        if case.wrist is not None:
            streams.append(("wrist", case.wrist[0], case.wrist[1]))
        for name, t, xyz in streams:
            centred = xyz - np.nanmean(xyz, axis=0)
            for k, style in enumerate(("-", "--", ":")):
                ax.plot(t, centred[:, k], style, lw=0.8, marker=".", ms=2, label=name if k == 0 else None)
        for p in case.truth:
            ax.axvspan(p.t_start, p.t_end, color="tab:green" if p.dir.sum() >= 0 else "tab:red", alpha=0.12)
        ax.set_title(f"{case.name}  {case.hz:.0f} Hz  {1000 * case.noise_m:.2f} mm  {_truth_text(case)}", fontsize=8)
        ax.legend(fontsize=6, loc="upper right", ncol=4)
        ax.set_ylabel("m (centred)", fontsize=7)
    axes[-1, 0].set_xlabel("t (s)")
    fig.tight_layout()
    fig.savefig(path, dpi=80)
    plt.close(fig)


def main(argv: list[str] | None = None) -> int:
    """Print the summary table and write the PNG."""
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--seed", type=int, default=DEV_SEEDS[0], help="stress seed")
    parser.add_argument("--n", type=int, default=20, help="stress cases to draw")
    parser.add_argument("--real", action="store_true", help="show the real cases instead")
    parser.add_argument("--png", type=Path, default=None, help="where to draw (default /tmp/learn_corpus_*.png)")
    args = parser.parse_args(argv)
    cases = real_cases() if args.real else stress_cases(args.seed, args.n)
    for line in summary_lines(cases):
        print(line)
    png = args.png or Path(f"/tmp/learn_corpus_{'real' if args.real else args.seed}.png")
    draw(cases, png)
    print(f"wrote {png}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
