#!/usr/bin/python3
"""cosim_terra combine and curve end to end (the interface the sweep uses),
and the tool's errors on bad input.

usage: test_ter_cli.py PATH/cosim_terra"""
import json
import os
import subprocess
import sys
import tempfile

FAILS = []


def check(cond, msg):
    if not cond:
        FAILS.append(msg)
        print("FAIL:", msg, file=sys.stderr)


def run(tool, *args):
    p = subprocess.run([tool, *args], capture_output=True, text=True, timeout=60)
    return p.returncode, p.stdout + p.stderr


def read_record(path):
    meta, cols, rows = {}, None, []
    for line in open(path):
        line = line.strip()
        if line.startswith("#"):
            k, _, v = line[1:].partition(":")
            meta[k.strip()] = v.strip()
        elif cols is None:
            cols = line.split(",")
        elif line:
            rows.append([float(x) for x in line.split(",")])
    return meta, [dict(zip(cols, r)) for r in rows]


def main():
    tool = sys.argv[1]
    d = tempfile.mkdtemp(prefix="test_ter_cli_")
    # docs/terramechanics.md §1's dry sand (regression values at r = 0.3 m, b = 0.15 m, W = 1 kN) and a softer twin
    sand = {"n": 1.1, "k_c": 990, "k_phi": 1528.4e3, "c": 1040, "phi_deg": 28, "K": 0.025, "c1": 0.43, "c2": 0.32}
    soft = dict(sand, k_phi=1.2e6, phi_deg=26)
    files = []
    for i, s in enumerate((sand, soft)):
        files.append(os.path.join(d, f"soil_{i}.json"))
        json.dump({"soil": s, "plate_fit": {"z_min": 0.004 + 0.001 * i, "z_max": 0.05 - 0.002 * i}},
                  open(files[-1], "w"))
    params = os.path.join(d, "params.json")
    rc, out = run(tool, "combine", *files, "--out", params)
    check(rc == 0, f"combine failed: {out}")
    P = json.load(open(params))
    check(abs(P["soil"]["k_phi"] - 0.5 * (1528.4e3 + 1.2e6)) < 1e-6 and len(P["packings"]) == 2
          and P["std"]["phi_deg"] > 1, f"combine: {P}")
    check(P["sinkage_fit_range"] == [0.005, 0.048], f"combine: common sinkage range {P.get('sinkage_fit_range')}")

    ref = os.path.join(d, "ref.csv")
    rc, out = run(tool, "curve", "--params", files[0], "--radius", "0.3", "--width", "0.15", "--load", "1000",
                  "--slips", "0:0.4:0.1", "--out", ref)
    check(rc == 0, f"curve failed: {out}")
    meta, rows = read_record(ref)
    dp = [r["DP"] for r in rows]
    check(len(rows) == 5 and abs(dp[0] + 107.8) < 0.06 and abs(dp[4] - 67.2) < 0.06,
          f"curve: DP {dp} (reference: -107.8 ... +67.2)")
    check(all(abs(r["W"] - 1000) < 1e-6 for r in rows) and meta["load_N"] == "1000", "curve: load column / meta")

    rc, out = run(tool, "curve", "--params", params, "--radius", "0.272", "--width", "0.165", "--load", "500",
                  "--out", ref)
    check(rc == 0, f"curve with a band failed: {out}")
    meta, rows = read_record(ref)
    check(len(rows) == 31 and abs(rows[-1]["s"] - 0.3) < 1e-9, "default slips 0:0.3:0.01")
    for q in ("z", "DP", "T_over_r", "F_t", "R", "T"):
        ok = all(r[q + "_lo"] <= r[q] + 1e-9 and r[q] <= r[q + "_hi"] + 1e-9 and r[q + "_hi"] > r[q + "_lo"]
                 for r in rows)
        check(ok, f"band of {q} does not bracket the mean-parameter curve")
    check(all(b["DP"] > a["DP"] for a, b in zip(rows, rows[1:])), "DP must rise with slip")
    check(all(abs(r["T_over_r"] - r["T"] / 0.272) < 1e-6 * max(1, abs(r["T"])) for r in rows), "T_over_r = T/r")
    beyond = sum(r["z_hi"] > 0.048 for r in rows)
    check(meta.get("sinkage_fit_range_m") == "0.005..0.048" and int(meta["rows_beyond_fit_range"]) == beyond
          and (beyond == 0) == ("warning" not in out), f"extrapolation flag: {meta}, {beyond}, {out}")

    bad_soil = os.path.join(d, "bad.json")
    json.dump({"soil": dict(sand, kphi=3)}, open(bad_soil, "w"))
    no_dem = os.path.join(d, "no_dem.json")
    json.dump({"processes": {"fem": {"exec": "fem_server"}}}, open(no_dem, "w"))
    file_bed = os.path.join(d, "file_bed.json")
    json.dump({"processes": {"soil": {"exec": "dem_server", "particles": {"file": "x.h5"}}}}, open(file_bed, "w"))
    broken = os.path.join(d, "broken.json")
    open(broken, "w").write('{"soil": {"n": 1,,}}')
    cases = [
        (["curve", "--params", files[0], "--radius", "0.3", "--width", "0.15", "--load", "1000"], "--out"),
        (["curve", "--params", files[0], "--radius", "0.3", "--width", "0.15", "--load", "1000", "--slips",
          "0.5:0.1:0.1", "--out", ref], "--slips"),
        (["curve", "--params", bad_soil, "--radius", "0.3", "--width", "0.15", "--load", "1000", "--out", ref],
         "soil.kphi"),
        (["curve", "--params", broken, "--radius", "0.3", "--width", "0.15", "--load", "1000", "--out", ref],
         "broken.json:1:"),
        (["curve", "--params", files[0], "--radius", "0.3", "--width", "0.15", "--load", "1e9", "--out", ref],
         "immobilised"),
        (["curve", "--params", files[0], "--radius", "x", "--width", "0.15", "--load", "1", "--out", ref],
         "--radius"),
        (["combine", files[0], "--out", params], "need >= 2"),
        (["fit", "--plate", files[0], "--out", params], "need >= 2 --plate"),
        (["plate", os.path.join(d, "none.json"), "--width", "0.1", "--out", ref], "none.json"),
        (["shear", files[0], "--sigma", "1000", "--out", ref], "no 'processes'"),
        (["plate", files[0], "--wdith", "0.1", "--out", ref], "unknown option '--wdith'"),
        (["shear", no_dem, "--sigma", "1000", "--out", ref], "dem_server"),
        (["dig"], "unknown command"),
        # the preparation options (terra/README.md, "Preparation") and the prepared bed
        (["shear", no_dem, "--sigma", "1000", "--prep-rolling", "0.1", "--out", ref], "needs --prep-friction"),
        (["plate", no_dem, "--width", "0.1", "--prep-friction", "-1", "--out", ref], "--prep-friction -1"),
        (["bed", no_dem, "--out", ref], "dem_server"),
        (["bed", file_bed, "--out", ref], "must be a generated bed"),
        (["bed", file_bed, "--particles", "[1, 2]", "--out", ref], "--particles: expected a JSON object"),
        (["bed", files[0]], "--out"),
    ]
    for args, needle in cases:
        rc, out = run(tool, *args)
        check(rc == 1 and needle in out, f"{' '.join(args[:2])}...: expected exit 1 with '{needle}', got {rc}: {out}")
    import shutil
    shutil.rmtree(d)
    if FAILS:
        print(f"test_ter_cli: {len(FAILS)} check(s) failed", file=sys.stderr)
        return 1
    print("test_ter_cli: all checks passed")
    return 0


if __name__ == "__main__":
    sys.exit(main())
