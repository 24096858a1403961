#!/usr/bin/env python3
"""The three-code table of docs/lammps-laws.md ("The three-code table: registered
protocol"), computed from sealed case summaries.

Usage: pairs.py SUMMARY.json [SUMMARY.json ...] --chaos CHAOS.json --margin M > pairs.json

Each SUMMARY is the `summary.json` of one run of cases/penetration/three-code-ci.toml
(`granval compare` for native + LIGGGHTS, `granval analyze` of a `deck --engine lammps`
directory for LAMMPS), each beside its verified `run-seal.json`. Every engine's per-bed
K_phi (`k_phi_beds`: each bed's own FDR over regime C, the engine gate's per-bed value)
is taken once; the beds must be the same (`bed_hashes`). For each pair of codes (a, b):
the per-bed ln(K_a / K_b); its mean with the two-sided 90 % t interval (n - 1 degrees
of freedom), decided as docs/statistics.md's equivalence (Schuirmann's two one-sided
tests, one comparison: PASS when the interval lies inside (-M, M), FAIL when it lies
wholly outside, else INCONCLUSIVE); and the agreement against chaos as the release
suite's "Engine agreement against chaos" section computes it (the 95 % interval of the
mean, F = sd^2 / s_c^2 with s_c = sqrt(mean c_k^2) of the chaos record, its upper-tail
p with (n - 1, len(c)) degrees of freedom). The same per-bed values and rules as
`src/numerics/stats.rs` and `src/compare/chaos.rs`; the native-LIGGGHTS row must
reproduce the K_phi gate of the `compare` report, which is its check.
"""
import itertools
import json
import math
import sys

from scipy import stats


def main(argv):
    paths, chaos_path, margin = [], None, None
    it = iter(argv)
    for a in it:
        if a == "--chaos":
            chaos_path = next(it)
        elif a == "--margin":
            margin = float(next(it))
        else:
            paths.append(a)
    if not paths or chaos_path is None or margin is None:
        sys.exit("usage: pairs.py SUMMARY.json ... --chaos CHAOS.json --margin M")
    engines, hashes = {}, None
    for p in paths:
        s = json.load(open(p))
        if hashes is None:
            hashes = s["bed_hashes"]
        elif s["bed_hashes"] != hashes:
            sys.exit(f"{p}: other beds than {paths[0]}")
        for name, e in s["engines"].items():
            ks = e["k_phi_beds"]
            if name in engines and engines[name] != ks:
                sys.exit(f"{p}: {name} per-bed K_phi differ between summaries")
            engines[name] = ks
    chaos = json.load(open(chaos_path))["log_ratio"]
    s_c = math.sqrt(sum(c * c for c in chaos) / len(chaos))
    rows = []
    # The registered order: native - LIGGGHTS, native - LAMMPS, LIGGGHTS - LAMMPS.
    order = ["native", "liggghts", "lammps"]
    names = sorted(engines, key=lambda e: (order.index(e) if e in order else len(order), e))
    for a, b in itertools.combinations(names, 2):
        logs = [math.log(x / y) for x, y in zip(engines[a], engines[b])]
        n = len(logs)
        mean = sum(logs) / n
        sd = math.sqrt(sum((v - mean) ** 2 for v in logs) / (n - 1))
        se = sd / math.sqrt(n)
        t90 = stats.t.ppf(0.95, n - 1)
        t95 = stats.t.ppf(0.975, n - 1)
        lo, hi = mean - t90 * se, mean + t90 * se
        if -margin < lo and hi < margin:
            decision = "PASS"
        elif lo > margin or hi < -margin:
            decision = "FAIL"
        else:
            decision = "INCONCLUSIVE"
        f = (sd / s_c) ** 2
        rows.append(
            {
                "pair": f"{a} / {b}",
                "beds": n,
                "per_bed_ln_ratio": logs,
                "mean": mean,
                "sd": sd,
                "interval90": [lo, hi],
                "margin": margin,
                "equivalence": decision,
                "interval95": [mean - t95 * se, mean + t95 * se],
                "chaos_sd": s_c,
                "chaos_df": len(chaos),
                "f_ratio": f,
                "f_p": float(stats.f.sf(f, n - 1, len(chaos))),
                "z_chaos": mean / (s_c / math.sqrt(n)),
            }
        )
    json.dump({"k_phi_beds": engines, "bed_hashes": hashes, "pairs": rows}, sys.stdout, indent=2)
    print()


if __name__ == "__main__":
    main(sys.argv[1:])
