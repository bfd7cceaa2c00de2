#!/usr/bin/env python3
"""How hard the input readers have been fuzzed: runs every libFuzzer harness
of a fuzz build (tools/run-tests.sh makes one in build-fuzz) for a while,
from the tree's corpus, and writes the section "Fuzzing" of
bench/results/reliability.md: executions, seconds, coverage reached, and
crashes (a crash input is left in the scratch directory and named here).
The defects found earlier and fixed are the corpus' regress_* inputs.

    /usr/bin/python3 bench/reliability/run_fuzz.py [--build build-fuzz]
        [--seconds 120] [--out bench/results/reliability.md]
"""
import argparse
import os
import re
import subprocess
import sys
import tempfile
import time

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
from mdsection import write_section  # noqa: E402

ROOT = os.path.abspath(os.path.join(os.path.dirname(__file__), "..", ".."))
CORPUS = os.path.join(ROOT, "tests", "fuzz", "corpus")
STAT = re.compile(r"stat::(\w+):\s+(\d+)")
COV = re.compile(r"cov: (\d+) ft: (\d+)")


def one(exe, name, seconds, scratch):
    art = os.path.join(scratch, name + "-")
    work = os.path.join(scratch, name)
    os.makedirs(work, exist_ok=True)
    t0 = time.time()
    p = subprocess.run([exe, f"-max_total_time={seconds}", "-timeout=10", "-rss_limit_mb=2048",
                        "-malloc_limit_mb=1024", "-print_final_stats=1", f"-artifact_prefix={art}",
                        work, os.path.join(CORPUS, name)], capture_output=True, text=True)
    wall = time.time() - t0
    stats = {k: int(v) for k, v in STAT.findall(p.stderr)}
    cov = COV.findall(p.stderr)
    crashes = [f for f in os.listdir(scratch) if f.startswith(name + "-")]
    regress = [f for f in os.listdir(os.path.join(CORPUS, name)) if f.startswith("regress_")]
    return {"name": name, "rc": p.returncode, "wall": wall,
            "execs": stats.get("number_of_executed_units", 0), "cov": cov[-1][0] if cov else "?",
            "crashes": crashes, "regress": len(regress)}


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--build", default="build-fuzz")
    ap.add_argument("--seconds", type=int, default=120)
    ap.add_argument("--out", default=os.path.join(ROOT, "bench", "results", "reliability.md"))
    a = ap.parse_args()
    bindir = os.path.join(a.build, "bin")
    names = sorted(n for n in os.listdir(CORPUS) if os.path.isfile(os.path.join(bindir, n)))
    if not names:
        sys.exit(f"no fuzz harnesses in {bindir}: build with -DCMAKE_C_COMPILER=clang -DCOSIM_FUZZ=ON")
    scratch = tempfile.mkdtemp(prefix="cosim-fuzz-")
    rows = []
    for n in names:
        r = one(os.path.join(bindir, n), n, a.seconds, scratch)
        print(n, r, flush=True)
        rows.append(r)
    lines = [f"Every libFuzzer harness (tests/fuzz/, ASan + UBSan, clang) run for {a.seconds} s from the "
             f"tree's corpus on {time.strftime('%Y-%m-%d')}, load average {os.getloadavg()[0]:.1f} at the end; "
             "`/usr/bin/python3 bench/reliability/run_fuzz.py` regenerates this section. "
             "`tools/run-tests.sh` fuzzes each harness for 20 s more in every CI run. Fixed defects are "
             "kept as `regress_*` inputs of the corpus, replayed by ctest in every build.", "",
             "| harness | executions | s | coverage (edges) | crashes in this run | fixed defects kept (regress_*) |",
             "|---|---|---|---|---|---|"]
    for r in rows:
        crash = ", ".join(os.path.join(scratch, c) for c in r["crashes"]) or "none"
        lines.append(f"| {r['name']} | {r['execs']:,} | {r['wall']:.0f} | {r['cov']} | {crash} | {r['regress']} |")
    total = sum(r["execs"] for r in rows)
    lines += ["", f"Total: {total:,} executions in {sum(r['wall'] for r in rows) / 3600:.2f} h.", ""]
    write_section(a.out, "Fuzzing", "\n".join(lines))
    print("\n".join(lines))
    return 1 if any(r["crashes"] for r in rows) else 0


if __name__ == "__main__":
    sys.exit(main())
