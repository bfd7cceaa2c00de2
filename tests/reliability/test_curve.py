"""security.curve (README "Security"): CURVE with a ZAP handler on every
endpoint the coupler binds.
- Launched: the participants get their key file through the environment
  (0600, in the private run dir; the keys are on no command line); the run
  goes as without CURVE; a monitor with the run's monitor key receives, one
  without keys receives nothing; the key files are gone after the run.
- --attach: the coupler prints the coupler's public key and, per
  participant, the key file and command line. An impostor without keys, or
  with keys of its own, gets no reply to its hello and cannot publish on the
  bus; the run is not disturbed; the participant started as printed runs
  the scene.
- --attach without CURVE: a process with a name the scene does not have is
  logged and ignored (it cannot end the run); the bus's publishing side is
  ipc in the private directory, not tcp."""
import json
import os
import subprocess
import threading
import time

import zmq

from rel import check
from common import BIN, COSIM, done, h5, no_orphans, processes_with, scene, write

if not zmq.has("curve"):
    print("SKIP: this libzmq has no CURVE")
    raise SystemExit(77)


def block_scene(name, end, **kw):
    s = scene(name, {"block": {"exec": "block_stub", "stiffness": 3e5}},
              scenario={"kind": "indentation", "profile": "linear", "depth": 1e-4,
                        "ramp_time": 1}, **kw)
    s["time"] = {"dt": 1e-3, "end": end}
    s["output"]["every"] = 100
    return s


def endpoints(s, wait=10):
    path = os.path.join(s["output"]["dir"], "endpoints.json")
    for _ in range(int(wait / 0.02)):
        if os.path.exists(path):
            try:
                return json.load(open(path))
            except ValueError:
                pass
        time.sleep(0.02)
    return {}


def receive(ep, keyfile, seconds, topics=(b"",)):
    """What a SUB gets from ep in `seconds` (as a CURVE client with keyfile)."""
    sub = zmq.Context.instance().socket(zmq.SUB)
    sub.setsockopt(zmq.LINGER, 0)
    if keyfile:
        k = json.load(open(keyfile))
        sub.curve_serverkey, sub.curve_publickey, sub.curve_secretkey = (
            k["server_public"].encode(), k["public"].encode(), k["secret"].encode())
    for t in topics:
        sub.setsockopt(zmq.SUBSCRIBE, t)
    sub.connect(ep)
    got, until = [], time.time() + seconds
    while time.time() < until:
        if sub.poll(50):
            got.append(sub.recv_multipart()[0].decode(errors="replace"))
    sub.close()
    return got


# --- launched with CURVE
s = block_scene("curve", 30.0, bus={"monitor": "tcp://127.0.0.1:0"}, security={"curve": True})
p = subprocess.Popen([COSIM, "run", write(s), "--quiet"], stdout=subprocess.PIPE,
                     stderr=subprocess.PIPE, text=True)
eps = endpoints(s)
key = eps.get("monitor_key_file", "")
check(eps.get("curve_server_public") and key and os.stat(key).st_mode & 0o777 == 0o600,
      f"endpoints.json names the coupler's key and a 0600 monitor key file ({eps})")
run_dir = os.path.dirname(key)
check(os.stat(run_dir).st_mode & 0o777 == 0o700, "in the private 0700 run directory")
part = [pid for pid, cmd in processes_with(s["name"]) if "--name block" in cmd]
secrets = [json.load(open(os.path.join(run_dir, f)))["secret"]
           for f in os.listdir(run_dir) if f.endswith(".key")]
if part:
    cmdline = open(f"/proc/{part[0]}/cmdline", "rb").read().decode()
    environ = open(f"/proc/{part[0]}/environ", "rb").read().decode()
    check(not any(k in cmdline for k in secrets), "no key on the participant's command line")
    check(f"COSIM_CURVE_FILE={run_dir}/block.key" in environ,
          "its key file comes in the environment")
keyed = receive(eps["bus_monitor"], key, 1.0)
stranger = receive(eps["bus_monitor"], None, 1.0)
check(any(t == "block.series" for t in keyed), f"a monitor with the monitor key receives "
      f"({len(keyed)} messages)")
check(not stranger, f"a monitor without keys receives nothing ({len(stranger)} messages)")
out, err = p.communicate(timeout=120)
check(p.returncode == 0 and len(h5(s)["/block/series"]) == 30000,
      f"the launched CURVE run finishes complete ({p.returncode}: {err[-300:]})")
check(not os.path.exists(run_dir), "the key files and run directory are gone after the run")
no_orphans(s, "curve launched")

# --- --attach with CURVE: impostors get nothing, the keyed participant runs
s = block_scene("curve_attach", 2.0, bus={"monitor": "tcp://127.0.0.1:0"},
                security={"curve": True})
s["coupling"] = {"attach_endpoint": "tcp://127.0.0.1:0", "hello_timeout": 30, "step_timeout": 5}
coupler = subprocess.Popen([COSIM, "run", write(s), "--attach", "--quiet"],
                           stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
line, printed = "", []
while "--endpoint" not in line and coupler.poll() is None:
    line = coupler.stderr.readline()
    printed.append(line)
while "public key" not in printed[-1] and coupler.poll() is None:
    printed.append(coupler.stderr.readline())
words = line.split()
env_kv = next((w for w in words if w.startswith("COSIM_CURVE_FILE=")), "=")
keyfile = env_kv.split("=", 1)[1]
ep = words[words.index("--endpoint") + 1] if "--endpoint" in words else ""
check(keyfile and os.path.exists(keyfile) and ep.startswith("tcp://"),
      f"--attach prints the key file and the command line ({line.strip()})")
check("public key is" in printed[-1], f"and the coupler's public key ({printed[-1].strip()})")
ctx = zmq.Context.instance()


def impostor(curve_keys):
    d = ctx.socket(zmq.DEALER)
    d.setsockopt(zmq.LINGER, 0)
    d.setsockopt(zmq.IDENTITY, b"block")
    if curve_keys:
        pub, sec = zmq.curve_keypair()
        d.curve_serverkey = json.load(open(keyfile))["server_public"].encode()
        d.curve_publickey, d.curve_secretkey = pub, sec
    d.connect(ep)
    hello = {"v": 1, "type": "hello", "step": 0, "t": 0.0, "arrays": [], "role": "block",
             "name": "block", "pid": 1}
    try:
        d.send_multipart([b"block", json.dumps(hello).encode()], zmq.NOBLOCK)
    except zmq.Again:
        pass
    got = d.poll(1500)
    d.close()
    return got


check(not impostor(False), "an impostor without keys gets no reply to its hello")
check(not impostor(True), "an impostor with keys of its own gets no reply either")
# an outside publisher on the bus's inner side (tcp with CURVE) reaches no monitor
inner = endpoints(s).get("bus_inner", "")
pub = ctx.socket(zmq.PUB)
pub.setsockopt(zmq.LINGER, 0)
pub.connect(inner)
mon_key = endpoints(s).get("monitor_key_file", "")
seen = []
th = threading.Thread(target=lambda: seen.extend(receive(endpoints(s)["bus_monitor"], mon_key, 2.5,
                                                         (b"forged",))))
th.start()
for _ in range(20):
    pub.send_multipart([b"forged.series", b"{}"])
    time.sleep(0.05)
# now the real participant, as printed
real = subprocess.Popen([os.path.join(BIN, "block_stub"), "--endpoint", ep, "--name", "block"],
                        env=dict(os.environ, COSIM_CURVE_FILE=keyfile),
                        stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
out, err = coupler.communicate(timeout=120)
real.wait(timeout=30)
th.join()
pub.close()
check(not seen, f"nothing published from outside reaches a monitor ({seen[:3]})")
check(coupler.returncode == 0 and real.returncode == 0 and len(h5(s)["/block/series"]) == 2000,
      f"the keyed participant runs the scene ({coupler.returncode}, {real.returncode}: "
      f"{err[-300:]})")
check("refused a connection" in err, f"the coupler logs the refused clients ({err[-300:]})")

# --- --attach without CURVE: a stranger is ignored, the bus is private
s = block_scene("attach_stranger", 2.0, bus={"monitor": "tcp://127.0.0.1:0"})
s["coupling"] = {"attach_endpoint": "tcp://127.0.0.1:0", "hello_timeout": 30, "step_timeout": 5}
coupler = subprocess.Popen([COSIM, "run", write(s), "--attach", "--quiet"],
                           stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
line = ""
while "--endpoint" not in line and coupler.poll() is None:
    line = coupler.stderr.readline()
ep = line.split("--endpoint")[1].split()[0]
check(endpoints(s).get("bus_inner", "").startswith("ipc://"),
      f"the bus's publishing side is ipc, not tcp ({endpoints(s).get('bus_inner')})")
d = ctx.socket(zmq.DEALER)
d.setsockopt(zmq.LINGER, 0)
d.setsockopt(zmq.IDENTITY, b"intruder\x1b[31m")
d.connect(ep)
d.send_multipart([b"intruder", b'{"v": 1, "type": "hello", "role": "block"}'])
d.send_multipart([b"intruder", b"not json"])
time.sleep(0.5)
d.close()
real = subprocess.Popen([os.path.join(BIN, "block_stub"), "--endpoint", ep, "--name", "block"],
                        stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
out, err = coupler.communicate(timeout=120)
real.wait(timeout=30)
check(coupler.returncode == 0 and len(h5(s)["/block/series"]) == 2000,
      f"a stranger does not end the run ({coupler.returncode}: {err[-300:]})")
check("ignoring a message from 'intruder?[31m'" in err and "\x1b" not in err,
      f"it is logged, with its name made printable ({err[-300:]!r})")
done()
