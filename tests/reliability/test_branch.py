"""`cosim run --branch CHECKPOINT`: a new run, in its own output.dir, from a
checkpoint's state, on the default scene shortened as in test_restart_tyre
(the tread on the grains and travelling before the checkpoint of step N).

- A branch under the checkpoint's own scheme (implicit) is bit for bit the
  straight run after step N: its results.h5 holds the rows and snapshots
  after N only, equal to the straight run's (wall-clock columns aside). The
  checkpoint carries the implicit scheme's defect and IQN-ILS history, so
  this holds only if the branch takes them.
- A branch from a serial run's checkpoint under the implicit scheme (the
  checkpoint has no implicit state: the scheme's state starts as at step 0)
  runs, iterates (more than one iteration in some steps, every step
  converged) and starts from the checkpoint's grains and tread: its first
  snapshot is within 0.05 of a grain's radius of the serial run's at the
  same step, a tenth of what the grains moved since the first snapshot.
- Refused (exit 1, the earlier run untouched): a branch into the
  checkpoint's own directory, `--branch latest`, a branch that changes a key
  other than the scheme (time.dt, named), --restart under another scheme
  (named), --restart with --branch, a branch over kept results without
  --overwrite."""
import hashlib
import os

import h5py
import numpy as np

from rel import ROOT, WALL_COLUMNS, WALL_DATASETS, check, cosim, datasets
from common import done, scratch

SCENE = os.path.join(ROOT, "configs", "default.json")
N, DT, EVERY = 160, 5e-5, 40
base = scratch("cosim-branch-")
common = ["--quiet", "--set", f"name=branch_{os.getpid()}", "--set", f"checkpoint.every={N}",
          "--set", f"output.every={EVERY}", "--set", "scenario.sinkage_velocity=2.5",
          "--set", "scenario.sinkage_force=5", "--set", f"time.end={2 * N * DT!r}"]
IMPLICIT = ["--set", 'coupling.scheme="implicit"']


def run(out, *extra):
    return cosim("run", SCENE, *common, "--set", f"output.dir={out}", *extra)


def ckpt(d):
    return os.path.join(d, f"checkpoint_{N}.h5")


def columns(ds):
    return [c.decode() if isinstance(c, bytes) else str(c) for c in ds.attrs.get("columns", [])]


def tail_differences(whole, branch):
    """What differs between the straight run's results after step N and the
    branch's: series rows (the branch holds only the last ones), snapshots
    after N; the branch must hold nothing else."""
    fa = h5py.File(os.path.join(whole, "results.h5"), "r")
    fb = h5py.File(os.path.join(branch, "results.h5"), "r")
    da, db = datasets(fa), datasets(fb)
    diff, same = [], 0
    for k, y in db.items():
        if k in WALL_DATASETS:
            continue
        if k not in da:
            diff.append(f"only in the branch: {k}")
            continue
        x, y = da[k][()], y[()]
        cols = columns(da[k])
        if cols:
            keep = [i for i, c in enumerate(cols) if c not in WALL_COLUMNS]
            x, y = x[N:, keep], y[:, keep]
        if x.shape != y.shape or x.tobytes() != y.tobytes():
            diff.append(f"{k}: {x.shape} vs {y.shape}")
        else:
            same += 1
    for k in da:
        parts = k.split("/")
        if len(parts) > 3 and parts[2] == "steps" and int(parts[3]) > N and k not in db:
            diff.append(f"snapshot missing in the branch: {k}")
    return diff, same


def digest(d):
    return hashlib.sha256(open(os.path.join(d, "results.h5"), "rb").read()).hexdigest()


# --- the same scheme: bit for bit the straight run after N
imp, imp_branch = os.path.join(base, "implicit"), os.path.join(base, "implicit_branch")
rc, out, err = run(imp, *IMPLICIT)
check(rc == 0 and os.path.exists(ckpt(imp)), f"implicit, 2N steps straight ({err[-300:]})")
rc, out, err = run(imp_branch, *IMPLICIT, "--branch", ckpt(imp))
check(rc == 0, f"branch under the same scheme ({err[-300:]})")
diff, same = tail_differences(imp, imp_branch)
check(not diff and same > 20, f"the branch equals the straight run after step {N}, bit for bit "
      f"({same} equal; differences: {diff[:5]})")
t = h5py.File(os.path.join(imp, "results.h5"), "r")["/coupler/traction"][()]
check(np.count_nonzero(t[:N, 4]) > 5, "the tread is on the grains before the checkpoint (the test "
      f"bites: {np.count_nonzero(t[:N, 4])} steps with load)")

# --- another scheme: a serial checkpoint continued under the implicit scheme
ser, ser_branch = os.path.join(base, "serial"), os.path.join(base, "serial_to_implicit")
rc, out, err = run(ser)
check(rc == 0 and os.path.exists(ckpt(ser)), f"serial, 2N steps straight ({err[-300:]})")
rc, out, err = run(ser_branch, *IMPLICIT, "--branch", ckpt(ser))
check(rc == 0, f"a serial checkpoint branched under the implicit scheme ({err[-300:]})")
fb = h5py.File(os.path.join(ser_branch, "results.h5"), "r")
series = fb["/coupler/series"]
cs = series[()]
it, conv = cs[:, columns(series).index("iterations")], cs[:, columns(series).index("converged")]
check(len(cs) == N and abs(cs[0, 0] - (N + 1) * DT) < 1e-12,
      f"the branch's rows start at step {N + 1} ({len(cs)} rows, first t = {cs[0, 0]})")
check(it.max() > 1 and conv.all(), f"the branch iterates (max {it.max():g} iterations) and every "
      f"step converged ({int(conv.sum())} of {len(conv)})")
fs = h5py.File(os.path.join(ser, "results.h5"), "r")
k1 = N + EVERY
x_branch, x_serial = fb[f"/dem/steps/{k1}/x"][()], fs[f"/dem/steps/{k1}/x"][()]
r = fs[f"/dem/steps/{k1}/r"][()]
moved = np.abs(x_serial - fs[f"/dem/steps/{EVERY}/x"][()]).max(axis=1) / r
apart = np.abs(x_branch - x_serial).max(axis=1) / r
# the two schemes part by 0.007 radius in 40 steps here; a branch from the
# settled bed (step 0) would be as far from the serial run as it moved
check(apart.max() < 0.05 and moved.max() > 10 * apart.max(),
      f"the branch starts from the checkpoint's grains: at step {k1} within {apart.max():.2g} "
      f"radius of the serial run (which moved up to {moved.max():.2g} radius since step {EVERY})")

# --- refused
before = digest(ser)
rc, out, err = run(ser, *IMPLICIT, "--branch", ckpt(ser))
check(rc == 1 and "own" in err and "directory" in err and digest(ser) == before,
      f"a branch into the checkpoint's own directory is refused ({err.strip()[-200:]})")
rc, out, err = run(os.path.join(base, "x1"), "--branch", "latest")
check(rc == 1 and "latest" in err, f"--branch latest is refused ({err.strip()[-200:]})")
rc, out, err = run(os.path.join(base, "x2"), "--set", "time.dt=2.5e-5", "--branch", ckpt(ser))
check(rc == 1 and "time.dt" in err, f"a branch that changes time.dt is refused, naming it "
      f"({err.strip()[-200:]})")
rc, out, err = run(os.path.join(base, "x3"), *IMPLICIT, "--restart", ckpt(ser))
check(rc == 1 and "coupling.scheme" in err, f"--restart under another scheme is refused, naming "
      f"it ({err.strip()[-200:]})")
rc, out, err = run(os.path.join(base, "x4"), "--restart", ckpt(ser), "--branch", ckpt(ser))
check(rc == 1 and "--branch" in err, f"--restart with --branch is refused ({err.strip()[-200:]})")
before = digest(ser_branch)
rc, out, err = run(ser_branch, *IMPLICIT, "--branch", ckpt(ser))
check(rc == 1 and "--overwrite" in err and digest(ser_branch) == before,
      f"a branch over kept results without --overwrite is refused ({err.strip()[-200:]})")
done()
