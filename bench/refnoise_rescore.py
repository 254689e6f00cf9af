#!/usr/bin/env python3
"""Re-scores a bench/compare.py run made before the reference-noise correction
(BENCHMARKS.md, "Method": each reference's own noise is subtracted).

Such a run scored every error against a single reference A (seed 100000), so each error carries
A's own noise Var(A), and Var(A) differs between renderers (Mitsuba's reference uses the
`independent` sampler, Trayecto's its stratified default). This script renders a second,
independent reference B (seed 200000, same spp, same renderer and default sampler, through
compare.py's own worker), estimates Var(A) = mean((A - B)^2 / (A^2 + 1e-2)) / 2, subtracts it from
the mean errors of the run's log (a constant per renderer commutes with the mean over rounds) and
prints compare.py's summary for the corrected ladders next to the uncorrected one.

Usage (in compare.py's venv, from the repository root; the run's bench/out/ must still hold A):

    bench/out/venv/bin/python bench/refnoise_rescore.py LOG --res 64 --ref-spp 512 \
        [--trayecto target/release/trayecto]

LOG is the run's printed output (the '[scene] renderer sampler: 4 spp 0.1 s relMSE ...' lines).
"""
import argparse
import json
import os
import re
import sys

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
import compare  # noqa: E402

LINE = re.compile(r"^\[(?P<scene>[^\]]+)\] (?P<r>\S+) ?(?P<smp>\S*): (?P<pts>\d+ spp .*)$")
POINT = re.compile(r"(\d+) spp ([0-9.]+) s relMSE ([0-9.eE+-]+)")


def parse_log(path):
    """{(scene, renderer): {"sampler": s, "rounds": [[(spp, time, relmse)], ...]}} in log order."""
    runs = {}
    for line in open(path):
        m = LINE.match(line.strip())
        if not m or "sweep" in line:
            continue
        pts = [(int(n), float(t), float(e)) for n, t, e in POINT.findall(m["pts"])]
        if not pts:
            continue
        entry = runs.setdefault((m["scene"], m["r"]), {"sampler": m["smp"] or None, "rounds": []})
        entry["rounds"].append(pts)
    return runs


def results_from(runs, noise):
    import numpy as np
    results = {}
    for (scene, r), v in runs.items():
        rounds = v["rounds"]
        sub = noise.get((scene, r.split(":")[0]), 0.0)
        ladder = []
        for k, (n, _, _) in enumerate(rounds[0]):
            err = float(np.mean([rd[k][2] for rd in rounds])) - sub
            ladder.append({"spp": n, "time": float(np.median([rd[k][1] for rd in rounds])),
                           "relmse": max(err, 0.01 * (err + sub))})
        results[(scene, r)] = {"ladder": ladder, "round_times": [[p[1] for p in rd] for rd in rounds],
                               "round_ids": list(range(len(rounds))), "sampler": v["sampler"]}
    return results


def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("log")
    ap.add_argument("--res", type=int, required=True)
    ap.add_argument("--ref-spp", type=int, required=True)
    ap.add_argument("--threads", type=int, default=os.cpu_count() or 1)
    ap.add_argument("--subdiv", type=int, default=8)
    ap.add_argument("--trayecto", default=os.path.join(compare.ROOT, "target", "release", "trayecto"))
    args = ap.parse_args()
    args.repeat = 1
    import numpy as np
    runs = parse_log(args.log)
    scenes = list(dict.fromkeys(sc for sc, _ in runs))
    renderers = list(dict.fromkeys(r for _, r in runs))
    noise = {}
    for scene in scenes:
        for kind in dict.fromkeys(r.split(":")[0] for sc, r in runs if sc == scene):
            a_path = os.path.join(compare.OUT, f"{scene}_{kind}_{args.res}px_{args.ref_spp}spp_ref.npy")
            b_path = a_path[:-4] + "_b.npy"
            if not os.path.exists(b_path):
                res, err = compare.run_worker(kind, scene, args, [{"spp": args.ref_spp, "seed": 200000,
                                                                   "reference": True, "out": b_path}])
                if res is None:
                    print(f"[{scene}] {kind}: second reference failed: {err}")
                    continue
            a = np.load(a_path).astype(np.float64)
            b = np.load(b_path).astype(np.float64)
            noise[(scene, kind)] = float(np.mean((a - b) ** 2 / (a ** 2 + 1e-2))) / 2
            print(f"[{scene}] {kind}: Var(reference) = {noise[(scene, kind)]:.3g} (relMSE units)", flush=True)
    for title, nz in (("as run (reference noise in every error)", {}), ("reference noise subtracted", noise)):
        print(f"\n### {title}\n")
        results = results_from(runs, nz)
        print("\n".join(compare.summary(results, scenes, renderers, max(len(v["rounds"]) for v in runs.values()))))
    print(json.dumps({f"{sc}/{k}": v for (sc, k), v in noise.items()}))
    return 0


if __name__ == "__main__":
    sys.exit(main())
