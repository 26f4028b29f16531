"""Accuracy of the learned chain: our method against the paper's plain method, in the same run.

Synthetic demonstrations (four scenes after the paper's tasks, three noise levels, several seeds), the
simulated scenes of ``pbd synth`` (microwave, sliding door, lever door, bottle cap; 20 seeds each, scored
against their ``truth.json`` by ``tasks.synth.score``) and every real Sturm track (``../shared/real/sturm``)
are written as recordings with the real ``RecordingWriter``, ingested into a temporary store and learned twice:
ours (change points + BIC + joint rigid-part fits) and the paper's plain method (one marker, spectral
segmentation with the given k, eq. (3) with T0 = 0.05, algebraic circle).

    .venv/bin/python bench/learn_accuracy.py [--quick]
"""

from __future__ import annotations

import argparse
import json
import sys
import tempfile
import time
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

REPO = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(REPO))

from bench.learn_corpus.case import Case, write_case  # noqa: E402
from bench.learn_corpus.real import real_cases_at  # noqa: E402
from bench.learn_corpus.score import score  # noqa: E402
from bench.learn_corpus.stress import DEV_SEEDS, HELDOUT_SEEDS, dev_cases, heldout_cases, stress_cases  # noqa: E402
from schemas.descriptor import Primitive  # noqa: E402
from tasks.errors import FitError  # noqa: E402
from tasks.fit.select import eigenvalue_ratio  # noqa: E402
from tasks.ingest.api import ingest_recording  # noqa: E402
from tasks.learn.api import learn_chain  # noqa: E402
from tasks.learn.params import LearnParams  # noqa: E402
from tasks.recording.load import load_recording  # noqa: E402
from tasks.recording.writer import RecordingWriter  # noqa: E402
from tasks.store import Store  # noqa: E402
from tasks.synth.paths import truth_path  # noqa: E402
from tasks.synth.record import synthesize  # noqa: E402
from tasks.synth.score import ChainScore, align_kinds, score_chain  # noqa: E402
from tests.learn.synthetic import SCENES, START_NS, TruthPrimitive, make_demo, write_recording  # noqa: E402

STURM = REPO.parent / "shared" / "real" / "sturm" / "mechanisms_iros_2010"
STURM_RADIUS = {"left_door": (0.344, 0.011), "right_door": (0.385, 0.006), "dishwasher": (0.656, 0.009)}
STURM_KIND = {"left_door": "rotation", "right_door": "rotation", "dishwasher": "rotation", "drawer": "translation"}
STURM_HZ = 30.0


@dataclass
class Errors:
    """Per-primitive errors of one method over the matched primitives."""

    chains_right: int = 0
    chains: int = 0
    direction_deg: list[float] = field(default_factory=list)
    position_mm: list[float] = field(default_factory=list)
    angle_deg: list[float] = field(default_factory=list)
    distance_mm: list[float] = field(default_factory=list)
    seconds: float = 0.0


def _score(chain: tuple[Primitive, ...], truth: tuple[TruthPrimitive, ...], err: Errors) -> None:
    kinds: list[str] = [p.kind for p in chain]
    want = [t.kind for t in truth]
    err.chains += 1
    err.chains_right += kinds == want
    for i, j in align_kinds(kinds, want):
        p, t = chain[i], truth[j]
        d = np.asarray(p.dir)
        err.direction_deg.append(float(np.degrees(np.arccos(np.clip(np.dot(d, t.dir), -1.0, 1.0)))))
        if t.kind == "rotation":
            w = np.asarray(p.pos) - t.pos
            err.position_mm.append(float(np.linalg.norm(w - np.dot(w, t.dir) * t.dir) * 1000.0))
            err.angle_deg.append(float(np.degrees(abs(p.extent - t.extent))))
        else:
            err.distance_mm.append(abs(p.extent - t.extent) * 1000.0)


def _stats(values: list[float]) -> str:
    if not values:
        return "-"
    v = np.asarray(values)
    return f"{np.median(v):.3f} / {np.percentile(v, 95):.3f} / {v.max():.3f}"


def _learn(store: Store, path: Path, params: LearnParams) -> tuple[tuple[Primitive, ...], float, list[str]]:
    """Chain, learning time (s) and segment kinds; a recording the method finds no motion in is an empty chain."""
    rec_id = ingest_recording(path, store).recording_id
    rec = load_recording(store, rec_id)
    t0 = time.perf_counter()
    try:
        result = learn_chain(rec, params, np.random.default_rng(0))
    except FitError:
        return (), time.perf_counter() - t0, []
    return result.chain, time.perf_counter() - t0, [f.kind for f in result.segments]


def synthetic(store: Store, folder: Path, quick: bool) -> None:
    noises = [0.0005] if quick else [0.0002, 0.0005, 0.001]
    seeds = range(1) if quick else range(5)
    ours, base = Errors(), Errors()
    cap_ours, cap_base = Errors(), Errors()
    by_noise: dict[float, Errors] = {n: Errors() for n in noises}
    failures: list[str] = []
    for scene in SCENES:
        for noise in noises:
            for seed in seeds:
                demo = make_demo(scene, np.random.default_rng(1000 + seed), noise_m=noise, hz=120.0)
                path = folder / f"{scene}-{noise * 1e4:.0f}-{seed}.mcap"
                write_recording(demo, path)
                chain, sec, _ = _learn(store, path, LearnParams())
                ours.seconds += sec
                _score(chain, demo.chain, ours)
                _score(chain, demo.chain, by_noise[noise])
                if [p.kind for p in chain] != [t.kind for t in demo.chain]:
                    failures.append(f"{path.name}: {[p.kind for p in chain]}")
                k = 2 * len(demo.chain) + 1  # what the object marker shows: rest, motion, rest, ...
                bchain, bsec, _ = _learn(store, path, LearnParams.paper_baseline(k=k))
                base.seconds += bsec
                _score(bchain, demo.chain, base)
                if scene == "bottle" and noise == 0.0005:
                    _score(chain, demo.chain, cap_ours)
                    _score(bchain, demo.chain, cap_base)
    n = ours.chains
    levels = ", ".join(f"{x * 1e3:g}" for x in noises)
    print(f"\nSynthetic demonstrations: {n} ({len(SCENES)} scenes x noise {levels} mm x {len(seeds)} seeds, 120 Hz)")
    print(f"{'figure (median / p95 / worst)':<34} {'ours':>26} {'paper baseline':>26}   target")
    rows = [
        ("chains right (kinds, order)", f"{ours.chains_right}/{n}", f"{base.chains_right}/{n}", "all"),
        ("axis direction error, deg", _stats(ours.direction_deg), _stats(base.direction_deg), "0.5 med, 2 worst"),
        ("axis position error, mm", _stats(ours.position_mm), _stats(base.position_mm), "2 med, 5 worst"),
        ("rotation angle error, deg", _stats(ours.angle_deg), _stats(base.angle_deg), "1"),
        ("translation distance error, mm", _stats(ours.distance_mm), _stats(base.distance_mm), "2"),
        ("learn time per demo, s", f"{ours.seconds / n:.2f}", f"{base.seconds / n:.2f}", ""),
    ]
    for name, a, b, target in rows:
        print(f"{name:<34} {a:>26} {b:>26}   {target}")
    print("\nBottle cap (2 cm cap, 0.5 mm noise), ours vs baseline:")
    for name, a, b in (
        ("chains right", f"{cap_ours.chains_right}/{cap_ours.chains}", f"{cap_base.chains_right}/{cap_base.chains}"),
        ("axis direction error, deg", _stats(cap_ours.direction_deg), _stats(cap_base.direction_deg)),
        ("axis position error, mm", _stats(cap_ours.position_mm), _stats(cap_base.position_mm)),
        ("rotation angle error, deg", _stats(cap_ours.angle_deg), _stats(cap_base.angle_deg)),
    ):
        print(f"{name:<34} {a:>26} {b:>26}")
    if len(noises) > 1:
        print("\nOurs by noise level (direction deg / position mm / angle deg / distance mm, worst):")
        for noise, e in by_noise.items():
            worst = [
                max(v) if v else float("nan") for v in (e.direction_deg, e.position_mm, e.angle_deg, e.distance_mm)
            ]
            print(f"  {noise * 1e3:g} mm: chains {e.chains_right}/{e.chains}, " + " / ".join(f"{w:.3f}" for w in worst))
    for f in failures:
        print(f"  wrong chain (ours): {f}")


SYNTH_SCENES = ("microwave", "sliding-door", "door", "bottle")


@dataclass
class SynthErrors(Errors):
    """Chains right and per-primitive errors of one method over ``pbd synth`` recordings, with boundaries."""

    boundary_s: list[float] = field(default_factory=list)
    wrong: list[str] = field(default_factory=list)

    def add(self, name: str, score: ChainScore) -> None:
        """Count one recording's score."""
        self.chains += 1
        self.chains_right += score.kinds_right
        if not score.kinds_right:
            self.wrong.append(f"{name}: {list(score.learned)} (truth {list(score.truth)})")
        for e in score.errors:
            self.direction_deg.append(e.direction_deg)
            if e.position_mm is not None:
                self.position_mm.append(e.position_mm)
            (self.angle_deg if e.kind == "rotation" else self.distance_mm).append(abs(e.extent_error))
            self.boundary_s += [abs(v) for v in (e.t_start_s, e.t_end_s) if v is not None]


def simulated(store: Store, folder: Path, quick: bool) -> None:
    """Both methods over ``pbd synth`` recordings of every built-in scene, scored against their truth."""
    seeds = range(3) if quick else range(20)
    ours, base = SynthErrors(), SynthErrors()
    per_scene = {s: (SynthErrors(), SynthErrors()) for s in SYNTH_SCENES}
    t_start = time.perf_counter()
    for scene in SYNTH_SCENES:
        for seed in seeds:
            path = folder / f"synth-{scene}-{seed}.mcap"
            synthesize(scene, seed, path)
            truth = json.loads(truth_path(path).read_text())
            name = f"{scene} seed {seed}"
            chain, _, _ = _learn(store, path, LearnParams())
            k = 2 * len(truth["chain"]) + 1  # rest, motion, rest, ... as the moving part shows it
            bchain, _, _ = _learn(store, path, LearnParams.paper_baseline(k=k))
            for who, got in ((ours, chain), (base, bchain)):
                score = score_chain([p.to_dict() for p in got], truth)
                who.add(name, score)
                per_scene[scene][0 if who is ours else 1].add(name, score)
    n = ours.chains
    print(f"\npbd synth recordings: {n} ({len(SYNTH_SCENES)} scenes x {len(seeds)} seeds, randomised instances)")
    print(f"{'figure (median / p95 / worst)':<34} {'ours':>26} {'paper baseline (true k)':>26}")
    rows = [
        ("chains right (kinds, order)", f"{ours.chains_right}/{n}", f"{base.chains_right}/{n}"),
        ("axis direction error, deg", _stats(ours.direction_deg), _stats(base.direction_deg)),
        ("axis position error, mm", _stats(ours.position_mm), _stats(base.position_mm)),
        ("rotation angle error, deg", _stats(ours.angle_deg), _stats(base.angle_deg)),
        ("translation distance error, mm", _stats(ours.distance_mm), _stats(base.distance_mm)),
        ("segment boundary error, s", _stats(ours.boundary_s), _stats(base.boundary_s)),
    ]
    for row, a, b in rows:
        print(f"{row:<34} {a:>26} {b:>26}")
    print("By scene: chains right ours / paper; ours worst direction deg, position mm, extent, boundary s")
    for scene, (o_err, b_err) in per_scene.items():
        worst = [max(v) if v else float("nan") for v in (o_err.direction_deg, o_err.position_mm)]
        extent = max(o_err.angle_deg or o_err.distance_mm or [float("nan")])
        bound = max(o_err.boundary_s or [float("nan")])
        unit = "deg" if o_err.angle_deg else "mm"
        print(
            f"  {scene:<14} {o_err.chains_right:>2}/{o_err.chains} {b_err.chains_right:>2}/{b_err.chains}   "
            f"{worst[0]:.2f} deg  {worst[1]:.2f} mm  {extent:.2f} {unit}  {bound:.2f} s"
        )
    for w in ours.wrong:
        print(f"  wrong chain (ours): {w}")
    print(f"  ({time.perf_counter() - t_start:.1f} s with recording)")


def _sturm_recording(log: Path, out: Path) -> None:
    pts = np.loadtxt(log)
    stamps = START_NS + np.round(np.arange(len(pts)) * 1e9 / STURM_HZ).astype(np.int64)
    with RecordingWriter(out, "mcap") as w:
        w.add_points("/robot/gripper", stamps, pts)


def real(store: Store, folder: Path, quick: bool) -> None:
    logs = sorted(STURM.glob("*/*.log"))
    if quick:
        logs = [sorted(STURM.glob(f"{m}/*.log"))[0] for m in STURM_KIND]
    right = {"ours": 0, "paper": 0}
    radii: dict[str, dict[str, list[float]]] = {m: {"ours": [], "paper": []} for m in STURM_RADIUS}
    ratios: list[tuple[float, str]] = []
    wrong: list[str] = []
    for log in logs:
        mech = log.parent.name
        path = folder / f"sturm-{mech}-{log.stem}.mcap"
        _sturm_recording(log, path)
        want = [STURM_KIND[mech]]
        chain, _, _ = _learn(store, path, LearnParams())
        bchain, _, _ = _learn(store, path, LearnParams.paper_baseline(k=1))
        right["ours"] += [p.kind for p in chain] == want
        right["paper"] += [p.kind for p in bchain] == want
        if [p.kind for p in chain] != want:
            wrong.append(f"{mech}/{log.name}: ours {[p.kind for p in chain]}")
        if bchain:
            ratios.append((eigenvalue_ratio(tuple(bchain[0].fit["eigenvalues"])), STURM_KIND[mech]))
        if mech in radii:
            radii[mech]["ours"] += [max(p.fit["radii_m"]) for p in chain if p.kind == "rotation"][:1]
            radii[mech]["paper"] += [max(p.fit["radii_m"]) for p in bchain if p.kind == "rotation"][:1]
    n = len(logs)
    print(f"\nReal Sturm tracks: {n} (one PointStamped marker at an assumed {STURM_HZ:g} Hz, written as MCAP)")
    print(f"{'figure':<34} {'ours':>26} {'paper baseline (k=1)':>26}")
    print(f"{'classified right':<34} {right['ours']:>22}/{n:<3} {right['paper']:>22}/{n:<3}")
    best = max((sum((r >= t0) == (k == "rotation") for r, k in ratios), t0) for t0 in np.geomspace(1e-4, 0.5, 200))
    print(f"{'eq. (3) at its best T0 (oracle)':<34} {'':>26} {best[0]:>22}/{len(ratios):<3}  (T0 = {best[1]:.4f})")
    rot = sorted(r for r, k in ratios if k == "rotation")
    pri = sorted(r for r, k in ratios if k == "translation")
    if rot and pri:
        spans = f"revolute {rot[0]:.4f}..{rot[-1]:.4f}, prismatic {pri[0]:.4f}..{pri[-1]:.4f}"
        print(f"  eq. (3) ratio lambda2/lambda1: {spans}")
    print(f"{'radius, m (mean +- std, n)':<34} {'ours':>26} {'paper baseline':>26}   README")
    for mech, (r0, s0) in STURM_RADIUS.items():
        cells = []
        for who in ("ours", "paper"):
            v = np.asarray(radii[mech][who])
            cells.append(f"{v.mean():.3f} +- {v.std():.3f} ({len(v)})" if len(v) else "-")
        print(f"  {mech:<32} {cells[0]:>26} {cells[1]:>26}   {r0:.3f} +- {s0:.3f}")
    for w in wrong:
        print(f"  wrong (ours): {w}")


@dataclass
class CorpusErrors:
    """Chains right and per-primitive errors of one method over a measuring corpus (``bench/learn_corpus``)."""

    right: int = 0
    right_strict: int = 0
    cases: int = 0
    direction_deg: list[float] = field(default_factory=list)
    position_mm: list[float] = field(default_factory=list)
    wrong: list[str] = field(default_factory=list)
    seconds: float = 0.0


def _corpus_run(store: Store, folder: Path, cases: list[Case], title: str) -> None:
    """Ours and the paper's method (true k) over corpus cases written as MCAP recordings; one table."""
    ours, paper = CorpusErrors(), CorpusErrors()
    run = Path(tempfile.mkdtemp(prefix="corpus-", dir=folder))
    for i, case in enumerate(cases):
        path = run / f"case-{i}.mcap"
        write_case(case, path)
        k = 2 * len(case.truth) + 1
        for who, params in ((ours, LearnParams()), (paper, LearnParams.paper_baseline(k=k))):
            chain, sec, _ = _learn(store, path, params)
            got = score([p.to_dict() for p in chain], case)
            who.cases += 1
            who.seconds += sec
            who.right += bool(got["right"])
            who.right_strict += bool(got["right"] and got.get("radius_ok") is not False)
            if not (got["right"] and got.get("radius_ok") is not False) and who is ours:
                who.wrong.append(f"{case.name}: {got['kinds_learned']} (truth {got['kinds_truth']})")
            for m in got["primitives"]:
                if m.get("direction_deg") is not None:
                    who.direction_deg.append(m["direction_deg"])
                if m.get("position_mm") is not None:
                    who.position_mm.append(m["position_mm"])
    n = len(cases)
    print(f"\n{title}: {n} cases")
    print(f"{'figure (median / p95 / worst)':<34} {'ours':>26} {'paper (true k)':>26}")
    for name, a, b in (
        ("chains right (kinds, count, order)", f"{ours.right}/{n}", f"{paper.right}/{n}"),
        ("... and radius within tolerance", f"{ours.right_strict}/{n}", f"{paper.right_strict}/{n}"),
        ("axis direction error, deg", _stats(ours.direction_deg), _stats(paper.direction_deg)),
        ("axis position error, mm", _stats(ours.position_mm), _stats(paper.position_mm)),
        ("learn time per recording, s", f"{ours.seconds / max(n, 1):.2f}", f"{paper.seconds / max(n, 1):.2f}"),
    ):
        print(f"{name:<34} {a:>26} {b:>26}")
    for w in ours.wrong:
        print(f"  wrong (ours): {w}")


def stress(store: Store, folder: Path, quick: bool, extra: range | None = None) -> None:
    """The stress corpus (``bench/learn_corpus/stress.py``): development seeds, then held-out seeds; ``extra``
    development seeds too when given (drawn while developing, beside the table's)."""
    per_seed = 4 if quick else 20
    _corpus_run(store, folder, dev_cases(per_seed), f"Stress corpus, development seeds {DEV_SEEDS}")
    _corpus_run(store, folder, heldout_cases(per_seed), f"Stress corpus, held-out seeds {HELDOUT_SEEDS}")
    if extra is not None:
        if held := sorted(set(extra) & set(HELDOUT_SEEDS)):
            raise SystemExit(f"--extra-stress-seeds: {held} are held out")
        cases = [case for seed in extra for case in stress_cases(seed, per_seed)]
        _corpus_run(store, folder, cases, f"Stress corpus, extra development seeds {extra.start}-{extra.stop - 1}")


def _seed_range(text: str) -> range:
    """``A-B`` (inclusive) as a range of seeds."""
    lo, _, hi = text.partition("-")
    return range(int(lo), int(hi or lo) + 1)


def real_corpus(store: Store, folder: Path, quick: bool) -> None:
    """Every labelled track of ``../shared/real`` at 10, 30 and 100 Hz (``bench/learn_corpus/real.py``). The
    Sturm mechanisms_iros_2010 tracks were used while developing; the others are reported apart."""
    cases = real_cases_at()
    if quick:
        cases = cases[::9]
    dev = [c for c in cases if "mechanisms_iros_2010" in c.name]
    held = [c for c in cases if "mechanisms_iros_2010" not in c.name]
    _corpus_run(store, folder, dev, "Real tracks (mechanisms_iros_2010: development) at 10, 30, 100 Hz")
    _corpus_run(store, folder, held, "Real tracks (second set, articulation_models, CHAMP: held out) at 10, 30, 100 Hz")


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument(
        "--quick", action="store_true", help="4 synthetic demonstrations, 12 pbd synth recordings and 4 real tracks"
    )
    parser.add_argument(
        "--only",
        choices=("synthetic", "synth", "real", "stress", "corpus-real"),
        help="run one section (default: all)",
    )
    parser.add_argument(
        "--extra-stress-seeds",
        type=_seed_range,
        metavar="A-B",
        help="also run these development seeds of the stress corpus (e.g. 4-31; none of them is held out)",
    )
    args = parser.parse_args()
    t0 = time.perf_counter()
    with tempfile.TemporaryDirectory(prefix="pbd-bench-learn-") as tmp:
        folder = Path(tmp)
        store = Store(folder / "store")
        if args.only in (None, "synthetic"):
            synthetic(store, folder, args.quick)
        if args.only in (None, "synth"):
            simulated(store, folder, args.quick)
        if args.only in (None, "real"):
            real(store, folder, args.quick)
        if args.only in (None, "stress"):
            stress(store, folder, args.quick, args.extra_stress_seeds)
        if args.only in (None, "corpus-real"):
            real_corpus(store, folder, args.quick)
    print(f"\ntotal {time.perf_counter() - t0:.1f} s")


if __name__ == "__main__":
    main()
