#!/usr/bin/env python3
"""What CURVE costs big messages, against the cipher's own limit (issue 25).

Data flow: the stub tyre scene with 150 x 150 surface nodes (six 0.54 MB
arrays per step: x and v to the dem and back from the fem, the nodal force
from the dem and to the fem; all dense: the stub's forces are non-zero at
every node and dem_stub gives no reach box) is run three ways: launched on
this host with the default transport (the arrays through shared memory,
PROTOCOL.md "Shared memory"), launched with coupling.transport "socket"
(the arrays as ipc frames), and over tcp on 127.0.0.1 with "socket" (the
wire: --attach, the participants started here from the command lines the
coupler prints); each with and without security.curve, alternated in rounds -> the coupler's loop time per step (its "Loop time"
line: the start and the handshake left out) -> min and median per mode;
bench_sodium (bench/proto/bench_sodium.c) -> libsodium's XSalsa20-Poly1305
throughput on this machine -> the floor CURVE cannot go under (every byte
encrypted once by the sender and decrypted once by the receiver) -> the
section "CURVE and the cipher" of bench/results/reliability.md.

    flock /tmp/cosim-bench.lock /usr/bin/python3 bench/reliability/bench_curve.py \
        [--bin build/bin] [--rounds 5] [--nodes 150] [--end 0.3]
"""
import argparse
import json
import os
import re
import shutil
import statistics
import subprocess
import sys
import tempfile

HERE = os.path.dirname(os.path.abspath(__file__))
ROOT = os.path.dirname(os.path.dirname(HERE))
sys.path.insert(0, HERE)
from mdsection import write_section  # noqa: E402

OUT = os.path.join(ROOT, "bench", "results", "reliability.md")
LOOP = re.compile(r"Loop time ([0-9.]+) s for (\d+) steps")
ARRAYS_PER_STEP = 6  # x, v to the dem; force from the dem; force to the fem; x, v from the fem


def scene(n, end, curve, tcp, transport):
    d = tempfile.mkdtemp(prefix="cosim-bench-curve-")
    s = {"name": f"benchcurve_{os.getpid()}",
         "time": {"dt": 1e-3, "end": end},
         "output": {"dir": os.path.join(d, "run"), "every": 1000},
         "scenario": {"kind": "tire_travel", "rim_center": [0, 0, 0.3], "sinkage_velocity": 0.1,
                      "sinkage_force": 20, "slip": 0.05, "omega": 1.8, "radius": 0.272},
         "processes": {
             "fem": {"exec": "fem_stub",
                     "surface": {"plane": {"size": [0.2, 0.16], "n": [n, n], "z": -0.27}}},
             "dem": {"exec": "dem_stub", "force_per_node": [-0.1, 0.0, 1.0], "ramp_time": 0.1}}}
    s["coupling"] = {"transport": transport}
    if curve:
        s["security"] = {"curve": True}
    if tcp:
        s["coupling"].update({"attach_endpoint": "tcp://127.0.0.1:0", "hello_timeout": 30})
    path = os.path.join(d, "scene.json")
    with open(path, "w") as f:
        json.dump(s, f)
    return d, path


def start_attached(binp, p):
    """Reads the coupler's attach lines and starts each participant."""
    kids = []
    while True:
        line = p.stderr.readline()
        if not line:
            raise SystemExit("the coupler ended before printing its attach lines")
        words = line.split()
        if "--endpoint" in words:
            env = dict(os.environ)
            if words[0].startswith("COSIM_CURVE_FILE="):
                env["COSIM_CURVE_FILE"] = words.pop(0).split("=", 1)[1]
            words[0] = os.path.join(binp, words[0])
            kids.append(subprocess.Popen(words, env=env, stdout=subprocess.DEVNULL,
                                         stderr=subprocess.DEVNULL))
        if len(kids) == 2:
            return kids


def loop_time(binp, n, end, curve, tcp, transport):
    d, path = scene(n, end, curve, tcp, transport)
    args = [os.path.join(binp, "cosim"), "run", path] + (["--attach"] if tcp else [])
    p = subprocess.Popen(args, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    kids = start_attached(binp, p) if tcp else []
    out, err = p.communicate(timeout=600)
    for k in kids:
        k.wait(timeout=60)
    shutil.rmtree(d, ignore_errors=True)
    m = LOOP.search(out)
    if p.returncode != 0 or not m:
        raise SystemExit(f"run failed ({p.returncode}): {err[-500:]}")
    return float(m.group(1)) / int(m.group(2))


def sodium(binp):
    exe = os.path.join(binp, "bench_sodium")
    out = subprocess.run([exe], capture_output=True, text=True, check=True).stdout
    rates = {}
    for line in out.splitlines():
        w = line.split()
        if len(w) == 3 and not line.startswith("#") and w[0] != "operation":
            rates[w[0]] = float(w[2])  # ms per MB
    return out, rates


def openssl_gcm(nbytes):
    """OpenSSL's AES-256-GCM on this machine (`openssl speed -evp`, the
    fastest AEAD here: AES-NI, VAES, PCLMUL): ms per MB, or None."""
    try:
        out = subprocess.run(["openssl", "speed", "-elapsed", "-seconds", "1", "-bytes",
                              str(nbytes), "-evp", "aes-256-gcm"], capture_output=True,
                             text=True, timeout=60).stdout
    except (OSError, subprocess.SubprocessError):
        return None
    for line in out.splitlines():
        w = line.split()
        if len(w) == 2 and w[0] == "AES-256-GCM" and w[1].endswith("k"):
            return 1e3 / (float(w[1][:-1]) / 1e3)  # 1000s of bytes per s -> ms per MB
    return None


def main():
    ap = argparse.ArgumentParser(description=__doc__,
                                 formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--bin", default="build/bin")
    ap.add_argument("--rounds", type=int, default=5)
    ap.add_argument("--nodes", type=int, default=150)
    ap.add_argument("--end", type=float, default=0.3)
    a = ap.parse_args()
    binp = os.path.abspath(a.bin)
    modes = [("same host (shared memory), no CURVE", False, False, "auto"),
             ("same host (shared memory), CURVE", True, False, "auto"),
             ("ipc frames, no CURVE", False, False, "socket"),
             ("ipc frames, CURVE", True, False, "socket"),
             ("tcp 127.0.0.1 frames, no CURVE", False, True, "socket"),
             ("tcp 127.0.0.1 frames, CURVE", True, True, "socket")]
    times = {m[0]: [] for m in modes}
    load0 = os.getloadavg()[0]
    sodium_out0, rate0 = sodium(binp)
    for r in range(a.rounds):
        for name, curve, tcp, transport in modes:
            times[name].append(loop_time(binp, a.nodes, a.end, curve, tcp, transport))
            print(f"round {r + 1}: {name}: {1e3 * times[name][-1]:.3f} ms/step", flush=True)
    sodium_out1, rate1 = sodium(binp)
    load1 = os.getloadavg()[0]
    rate = {k: min(rate0[k], rate1[k]) for k in rate0}
    mb = ARRAYS_PER_STEP * a.nodes * a.nodes * 3 * 8 / 1e6  # per step, through the cipher
    cipher = rate["box_afternm"] + rate["box_open_afternm"]  # ms per MB: sender + receiver
    floor = mb * cipher
    lines = [
        f"Stub tyre scene, {a.nodes} x {a.nodes} surface nodes: {ARRAYS_PER_STEP} arrays of "
        f"{a.nodes * a.nodes * 24 / 1e6:.2f} MB per step ({mb:.2f} MB per step through the "
        f"coupler). The coupler's loop time per step over {int(round(a.end / 1e-3))} steps, "
        f"the six modes alternated in {a.rounds} rounds in one sitting; load average "
        f"{load0:.1f} at the start, {load1:.1f} at the end (2 cores, shared). tcp: `--attach` on "
        f"tcp://127.0.0.1, the participants started from the printed lines. "
        f"`flock /tmp/cosim-bench.lock /usr/bin/python3 bench/reliability/bench_curve.py` "
        f"regenerates this section.", "",
        "| mode | min ms/step | median ms/step | ratio (min) | ratio (median) |",
        "|---|---|---|---|---|"]
    for i, (name, curve, tcp, transport) in enumerate(modes):
        base = modes[i - i % 2][0]
        mn, md = min(times[name]), statistics.median(times[name])
        lines.append(f"| {name} | {1e3 * mn:.3f} | {1e3 * md:.3f} | "
                     f"{mn / min(times[base]):.2f} | {md / statistics.median(times[base]):.2f} |")
    extra = {t: min(times[f"{t}, CURVE"]) - min(times[f"{t}, no CURVE"])
             for t in ("ipc frames", "tcp 127.0.0.1 frames")}
    lines += [
        "", "libsodium on this machine (`bench_sodium`, 0.54 MB buffers, the better of a run "
        "before and one after the rounds; ms per MB):", "",
        "| operation | ms/MB | MB/s |", "|---|---|---|"]
    for k in ("box_afternm", "box_open_afternm", "box_easy_afternm", "secretbox_easy",
              "zmq43_encode", "aes256gcm", "aes256gcm_decrypt", "memcpy"):
        if k in rate:
            lines.append(f"| {k} | {rate[k]:.3f} | {1e3 / rate[k]:.0f} |")
    gcm = openssl_gcm(a.nodes * a.nodes * 24)
    if gcm:
        lines.append(f"| OpenSSL AES-256-GCM (`openssl speed -evp`, encrypt) | {gcm:.3f} | "
                     f"{1e3 / gcm:.0f} |")
    best_base = min(times["tcp 127.0.0.1 frames, no CURVE"])
    lines += [
        "", f"The floor: CurveZMQ encrypts every frame with XSalsa20-Poly1305 "
        f"(`crypto_box_afternm`) in the sender and decrypts it in the receiver, so each step "
        f"costs at least {mb:.2f} MB x ({rate['box_afternm']:.3f} + "
        f"{rate['box_open_afternm']:.3f}) ms/MB = {floor:.2f} ms of cipher on the path of "
        f"the lock-step exchange when sender and receiver take turns, half of it "
        f"({floor / 2:.2f} ms) if they overlapped perfectly on two free cores. Measured "
        f"extra per step (min CURVE - min plain): ipc frames "
        f"{1e3 * extra['ipc frames']:.2f} ms, tcp frames "
        f"{1e3 * extra['tcp 127.0.0.1 frames']:.2f} ms, i.e. "
        f"{1e3 * extra['ipc frames'] / mb:.2f} and "
        f"{1e3 * extra['tcp 127.0.0.1 frames'] / mb:.2f} ms per MB moved, "
        f"{1e3 * extra['ipc frames'] / mb / cipher:.2f}x and "
        f"{1e3 * extra['tcp 127.0.0.1 frames'] / mb / cipher:.2f}x the cipher's {cipher:.2f} ms "
        f"per MB (encrypt + decrypt). The cipher is most of CURVE's cost; the rest is "
        f"libzmq 4.3's work around it per frame (two zero-filled buffers of the frame's size, "
        f"a copy in and a copy out: the zmq43_encode row, "
        f"{rate['zmq43_encode'] / rate['box_afternm']:.1f}x crypto_box_afternm alone when "
        f"every buffer is fresh memory) and the ZAP handler, asked once per connection. A "
        f"`perf record` of the ipc CURVE run (2026-12-02) had 62 % of all its samples in "
        f"libsodium, 6 % in libc (memmove), 1.5 % in libzmq. "
        f"For 1.3x plain tcp "
        f"({1e3 * best_base:.2f} ms) the cipher's share must fit in "
        f"{300 * best_base:.2f} ms per step: {mb:.2f} MB encrypted and decrypted in that "
        f"time even with perfect overlap needs {mb / (0.3 * 1e3 * best_base):.1f} GB/s per "
        f"core, {mb / (0.3 * 1e3 * best_base) / (1 / max(rate['box_afternm'], rate['box_open_afternm'])):.1f}x "
        f"what libsodium's XSalsa20-Poly1305 does on this machine; the lowest plain-tcp "
        f"ratio the cipher allows is {(best_base * 1e3 + floor / 2) / (best_base * 1e3):.2f}x "
        f"(perfect overlap) to {(best_base * 1e3 + floor) / (best_base * 1e3):.2f}x (none). "
        + (f"With the fastest AEAD on this machine, OpenSSL's AES-256-GCM at "
           f"{1e3 / gcm:.0f} MB/s (encrypt; decrypt taken as fast), in place of CurveZMQ's, the "
           f"floor would be {(best_base * 1e3 + mb * gcm) / (best_base * 1e3):.2f}x (perfect "
           f"overlap) to {(best_base * 1e3 + 2 * mb * gcm) / (best_base * 1e3):.2f}x (none). "
           if gcm else "")
        + (f"libsodium's own AES-256-GCM does {1e3 / rate['aes256gcm']:.0f} MB/s here. "
           if "aes256gcm" in rate else "")
        + f"On one host the arrays do not touch the wire: shared memory carries them and "
        f"CURVE encrypts only the messages' headers (first rows). Between hosts the wire "
        f"itself adds to both runs (arithmetic, not measured here): at 1 Gbit/s "
        f"({mb / 0.125:.0f} ms per step for {mb:.2f} MB) the cipher's {floor:.1f} ms make at "
        f"most {(mb / 0.125 + floor) / (mb / 0.125):.2f}x, at 10 Gbit/s "
        f"({mb / 1.25:.1f} ms) at most {(mb / 1.25 + floor) / (mb / 1.25):.2f}x.", ""]
    write_section(OUT, "CURVE and the cipher", "\n".join(lines))
    print("\n".join(lines))
    print(sodium_out1)


if __name__ == "__main__":
    main()
