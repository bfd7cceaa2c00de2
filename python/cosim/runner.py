"""Running scenes from Python: ``cosim run`` with its exit codes as
exceptions (README "What runs": 0 ok, 1 bad scene or usage, 3 a participant
failed, 4 output error, 130 interrupted).

    r = cosim.run("configs/tread_block.json", set={"time.end": 1e-3})
    r.series("block")["force"]
"""
import concurrent.futures
import itertools
import json
import os
import re
import shutil
import signal
import subprocess
import sys
import tempfile
import threading

from .errors import EXIT_ERRORS, RunError
from .results import Results
from .roles import cosim_executable
from .scene_sets import apply_sets
from .sweep_beds import Beds

STOP_WAIT_S = 60  # after SIGINT, cosim stops every participant and closes the file
FAILED_RE = re.compile(r"^cosim: run '.*?' failed: (.*?)(?=^cosim: |\Z)", re.S | re.M)
PARTICIPANT_RE = re.compile(r"^cosim: failed participant: (\S+)", re.M)
RESULTS_RE = re.compile(r"^results: (.*)/results\.h5", re.M)
KIND = {1: "bad scene or usage", 3: "a participant failed", 4: "output error",
        130: "interrupted"}


def _scene_file(scene):
    """(path, dict or None) of the scene: a dict is written to a temp file
    (removed by _done_with once the run succeeded: a failed run's error names
    it, so it stays)."""
    if isinstance(scene, dict):
        path = os.path.join(tempfile.mkdtemp(prefix="cosim-scene-"), "scene.json")
        with open(path, "w") as f:
            json.dump(scene, f, indent=1)
        return path, scene
    try:
        with open(scene) as f:
            return scene, json.load(f)
    except (OSError, ValueError):
        return scene, None  # cosim names what is wrong


def _done_with(scene, path):
    """Removes the temp folder _scene_file made for a dict scene."""
    if isinstance(scene, dict):
        shutil.rmtree(os.path.dirname(path), ignore_errors=True)


def _output_dir(data, sets):
    if "output.dir" in sets:
        return str(sets["output.dir"])
    try:
        return data["output"]["dir"]
    except (KeyError, TypeError):
        return None


def _pump(stream, keep, echo):
    for line in stream:
        keep.append(line)
        if echo:
            echo.write(line)
            echo.flush()


def _wait(p, timeout):
    """Waits for cosim; on Ctrl-C or timeout it is interrupted the way the
    terminal would (SIGINT: it stops the participants, keeps the results)."""
    try:
        p.wait(timeout)
        return None
    except KeyboardInterrupt:
        why = "interrupted (KeyboardInterrupt)"
    except subprocess.TimeoutExpired:
        why = f"did not finish within {timeout:g} s"
    p.send_signal(signal.SIGINT)
    try:
        p.wait(STOP_WAIT_S)
    except subprocess.TimeoutExpired:
        p.kill()
        p.wait()
    return why


def _error(path, rc, out, err, output_dir, why):
    m = FAILED_RE.search(err)
    reason = (m.group(1).strip() if m else
              "\n".join(l for l in err.strip().splitlines()[-3:])) or f"exit code {rc}"
    pm = PARTICIPANT_RE.search(err)
    who = pm.group(1) if pm else None
    kind = KIND.get(rc, f"exit code {rc}")
    if who:
        kind = f"participant '{who}' failed"
    if why:
        kind = f"{why}; {kind}"
    cls = EXIT_ERRORS.get(rc, RunError)
    return cls(f"cosim run {path}: {kind}: {reason}", returncode=rc, stdout=out, stderr=err,
               output_dir=output_dir, participant=who, reason=reason)


def run(scene, set=None, output_dir=None, cosim=None, quiet=True, timeout=None,
        args=(), cwd=None):
    """Runs a scene (a JSON file or a dict) with ``cosim run``.

    set         {key.path: value} overrides (``--set``), values as JSON
    output_dir  shorthand for set={"output.dir": ...}
    cosim       the cosim binary (default $COSIM_EXE, then PATH)
    quiet       capture cosim's output; False also prints it as it comes
    timeout     seconds; then the run is interrupted (Interrupted)
    args        further arguments to ``cosim run`` (e.g. ["--attach"])

    Returns :class:`Results` of the run's results.h5 (with ``.stdout`` and
    ``.stderr``); raises SceneError (exit 1), ParticipantError (3, with
    ``.participant``), OutputError (4), Interrupted (130) or RunError."""
    sets = dict(set or {})
    if output_dir is not None:
        sets["output.dir"] = output_dir
    path, data = _scene_file(scene)
    cmd = [cosim_executable(cosim), "run", path]
    for key, value in sets.items():
        cmd += ["--set", f"{key}={json.dumps(value)}"]
    cmd += list(args)
    out, err = [], []
    p = subprocess.Popen(cmd, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True,
                         cwd=cwd)
    pumps = [threading.Thread(target=_pump, args=(p.stdout, out, None if quiet else sys.stdout)),
             threading.Thread(target=_pump, args=(p.stderr, err, None if quiet else sys.stderr))]
    for t in pumps:
        t.start()
    why = _wait(p, timeout)
    for t in pumps:
        t.join()
    out, err = "".join(out), "".join(err)
    where = RESULTS_RE.search(out)
    outdir = where.group(1) if where else _output_dir(data, sets)
    if outdir and cwd and not os.path.isabs(outdir):
        outdir = os.path.join(cwd, outdir)
    if p.returncode != 0 or why:
        raise _error(path, p.returncode, out, err, outdir, why)
    _done_with(scene, path)
    r = Results(outdir)
    r.stdout, r.stderr = out, err
    return r


def settle(scene, beds, set=None, output_dir=None, **run_args):
    """Settle-only: runs the scene cut to one coupled step (``time.end`` =
    ``time.dt``), each dem process named in ``beds`` ({process: path})
    writing its settled bed with its whole state to that path
    (``particles.save``; dem_server saves at the end of its init, before
    the step, so the file holds the bed exactly as the full run would start
    from it). Loading it (``particles = {"file": path}``) then continues that
    run bit for bit. Returns the short run's :class:`Results`."""
    sets = dict(set or {})
    path, data = _scene_file(scene)
    eff = apply_sets(data or {}, sets)  # time.dt may come from --set
    try:
        sets["time.end"] = eff["time"]["dt"]
    except (KeyError, TypeError):
        raise RunError(f"cosim.settle {path}: the scene has no time.dt") from None
    for name, bed in beds.items():
        sets[f"processes.{name}.particles.save"] = bed
    args = list(run_args.pop("args", ()))
    if "--overwrite" not in args:
        args.append("--overwrite")  # the settle run's own folder
    r = run(path, set=sets, output_dir=output_dir, args=args, **run_args)
    _done_with(scene, path)
    return r


def finished(run_dir):
    """True if run_dir holds a results.h5 whose coupler rows reach the
    scene's time.end (within half a step): a run that needs no rerun."""
    try:
        with Results(run_dir) as r:
            sc, t = r.scene["time"], r.series("coupler")["t"]
            return len(t) > 0 and t[-1] >= sc["end"] - 0.5 * sc["dt"]
    except Exception:  # missing, damaged, cut short: run it
        return False


def _dir_name(point):
    text = ",".join(f"{k}={json.dumps(v) if not isinstance(v, str) else v}"
                    for k, v in point.items())
    return re.sub(r"[^A-Za-z0-9_.,=+-]", "_", text)


def grid_points(values):
    """Every combination of ``values`` ({key.path: [v0, v1, ...]}) as a
    {key.path: value} point, the first key varying slowest."""
    keys = list(values)
    return [dict(zip(keys, combo)) for combo in itertools.product(*(values[k] for k in keys))]


def concurrent_sets(sets, jobs, scene=None):
    """``sets`` for runs that share the machine (``jobs`` > 1): coupling.affinity
    "none" unless the caller set it. "handoff" binds a run's coupler and its
    participants' main threads to one core, the allowed core with the fewest
    threads bound to it alone when the run starts (coupler/affinity.c), which
    suits a run that has the machine; runs started at the same moment each
    read the bindings before the others have bound, so two may still share a
    core while another idles. With the ``scene`` (a path or dict), each
    fem_server process without a ``threads`` of its own (in the scene or in
    ``sets``) gets ``threads`` 1: on shared cores its other threads only wait
    at barriers (7-11 % of a sand-scene run's CPU, bench/results/tire_soil.md
    stop 60), and its results do not depend on the count. dem_server's
    "auto" already follows the load."""
    sets = dict(sets or {})
    if jobs > 1 and "coupling.affinity" not in sets:
        sets["coupling.affinity"] = "none"
    data = scene if scene is None or isinstance(scene, dict) else _scene_file(scene)[1]
    procs = data.get("processes") if isinstance(data, dict) else None
    if jobs > 1 and isinstance(procs, dict):
        for name, p in procs.items():
            key = f"processes.{name}.threads"
            if isinstance(p, dict) and os.path.basename(str(p.get("exec", ""))) == "fem_server" \
                    and "threads" not in p and key not in sets:
                sets[key] = 1
    return sets


def sweep(scene, values, out, set=None, jobs=1, keep_going=False, beds=None, resume=False,
          **run_args):
    """One run per combination of ``values`` ({key.path: [v0, v1, ...]},
    several keys: every combination), each into its own ``out/<key>=<value>``
    (ports are chosen free by each run). ``jobs`` runs at once.

    Returns [(point, Results)] in the order of the combinations, ``point``
    the {key.path: value} of the run. A failed run raises its RunError
    (naming the point) once the runs under way have ended; with
    ``keep_going`` the error takes the place of the Results instead.

    ``beds`` (a folder): every distinct bed is settled
    once into it (a settle-only run, :func:`settle`; a bed already there is
    not settled again) and each run loads its bed (cosim/sweep_beds.py).
    ``resume``: a point whose results.h5 already reaches time.end is not
    run again (its Results are returned); the others run with --overwrite.

    With ``jobs`` > 1 the runs get ``coupling.affinity`` "none" unless
    ``set`` gives it, and fem_server ``threads`` 1 unless the scene or ``set``
    gives it (:func:`concurrent_sets`).

    This loops over :func:`run`; ``cosim sweep`` (sweep_cli.py) adds the
    summary."""
    points = grid_points(values)
    set = concurrent_sets(set, jobs, scene)
    shared = None
    if beds:
        shared = Beds(scene, points, set, beds)
        shared.settle(points, settle, jobs=jobs, **run_args)

    def one(index):
        point = points[index]
        sets = dict(set or {}, **point)
        if shared:
            sets = shared.run_sets(index, sets)
        sets["output.dir"] = os.path.join(out, _dir_name(point))
        if resume and finished(sets["output.dir"]):
            return Results(sets["output.dir"])
        opts = dict(run_args)
        if resume:
            opts["args"] = list(opts.get("args", ())) + ["--overwrite"]
        try:
            return run(scene, set=sets, **opts)
        except RunError as e:
            e.args = (f"{_dir_name(point)}: {e}",)
            if keep_going:
                return e
            raise

    with concurrent.futures.ThreadPoolExecutor(max_workers=max(1, jobs)) as pool:
        results = list(pool.map(one, range(len(points))))
    return list(zip(points, results))
