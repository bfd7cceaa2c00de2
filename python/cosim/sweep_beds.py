"""Settled beds shared by the runs of a sweep (issue 21).

A tyre run spends much of its time settling its bed. The runs of a sweep that
differ only in what does not reach the bed (the scenario: slip, load, ...)
would settle the same bed again and again; so ``cosim sweep`` settles each
distinct bed once, into ``DIR/beds/``, and every run loads it:

1. plan: per point, the scene as that run would see it (``--set`` and the
   point applied); its dem processes that generate and settle a bed
   (``exec`` dem_server, ``particles.generate`` "bed", ``settle_max_steps``
   > 0); the bed's id, a hash of that scene without the keys that cannot
   change a bed (``name``, ``notes``, ``time.end``, ``output``, ``bus``, ``checkpoint``,
   ``security``, ``scenario`` but its ``rim_center``, each bed's
   ``particles.save``, ``coupling.affinity`` and the processes' ``threads``). Same id, same bed: with ``--repeat`` the beds are the
   seeds.
2. settle: for each id without its files, a settle-only run
   (:func:`cosim.runner.settle`: the point's scene cut to one coupled step;
   dem_server writes the bed, with its whole state, at the end of its init,
   before that step) into ``DIR/beds/bed-<id>/``, the beds to
   ``DIR/beds/bed-<id>-<dem>.h5`` (written under a temporary name and
   renamed, so a bed file is always whole), the scene it stands for to
   ``bed-<id>.json``, one line per settle run to ``settle.log``. A bed whose
   files are there is not settled again: a sweep resumed, or run again with
   more values, reuses them (delete ``DIR/beds`` to settle anew).
3. run: each point's dem gets ``particles = {"file": <its bed>}``: the saved
   state continues the settling run bit for bit (dem_server README, "Beds"),
   so each run's results equal those of the same point settling its own bed.
"""
import concurrent.futures
import copy
import hashlib
import json
import os
import re
import time

from .scene_sets import apply_sets

BEDS_DIR = "beds"
LOG_FILE = "settle.log"
# scene keys that a bed does not depend on (those a checkpoint restart may
# change, coupler/checkpoint.c, the scene's prose, and the scenario, which
# acts from step 1): an edit of the notes once gave every bed a new id
IGNORED = ("name", "notes", "output", "bus", "checkpoint", "security")
KEPT_SCENARIO = ("rim_center",)  # the tread's place while the bed settles
SETTLED_RE = re.compile(r"dem_server: bed of (\d+) grains settled in (\d+) steps \(([0-9.]+) s\)")
ID_LEN = 12


def settled_beds(scene):
    """Names of the dem processes that generate and settle a bed."""
    names = []
    for name, p in scene.get("processes", {}).items():
        if not isinstance(p, dict) or os.path.basename(str(p.get("exec", ""))) != "dem_server":
            continue
        part = p.get("particles")
        if isinstance(part, dict) and part.get("generate") == "bed" and \
                (part.get("settle_max_steps") or 0) > 0:
            names.append(name)
    return names


def bed_scene(scene, names):
    """The part of a scene a bed depends on."""
    s = {k: copy.deepcopy(v) for k, v in scene.items() if k not in IGNORED}
    s.get("time", {}).pop("end", None)
    if isinstance(s.get("coupling"), dict):
        s["coupling"].pop("affinity", None)  # where the processes run, not what they compute
        if not s["coupling"]:
            del s["coupling"]
    for p in s.get("processes", {}).values():
        if isinstance(p, dict):
            p.pop("threads", None)  # dem_server's and fem_server's results do not depend on it
    if "scenario" in s:
        s["scenario"] = {k: v for k, v in s["scenario"].items() if k in KEPT_SCENARIO}
    for n in names:
        s["processes"][n]["particles"].pop("save", None)
    return s


def bed_id(scene, names):
    text = json.dumps(bed_scene(scene, names), sort_keys=True, separators=(",", ":"))
    return hashlib.sha1(text.encode()).hexdigest()[:ID_LEN]


class Beds:
    """The beds of one sweep: plan (per point: id, dem names), settle, and the
    --set overrides that make a point's run load its bed."""

    def __init__(self, scene_path, points, sets, folder):
        if isinstance(scene_path, dict):
            self.scene = scene_path
        else:
            with open(scene_path) as f:
                self.scene = json.load(f)
        self.scene_path, self.sets, self.folder = scene_path, dict(sets or {}), folder
        self.plan = []  # per point: (id, names) or None
        for p in points:
            eff = apply_sets(self.scene, dict(self.sets, **p))
            names = settled_beds(eff)
            self.plan.append((bed_id(eff, names), names, eff) if names else None)

    def file(self, bid, name):
        return os.path.abspath(os.path.join(self.folder, f"bed-{bid}-{name}.h5"))

    def have(self, bid, names):
        return all(os.path.isfile(self.file(bid, n)) for n in names)

    def settle(self, points, settle, jobs=1, **run_args):
        """Settles each bed not yet there (the first point that needs it
        stands for it) by ``settle`` (:func:`cosim.runner.settle`, given by
        the caller: this module sits below the runner); returns the number of
        settle runs."""
        todo, seen = [], set()
        for p, plan in zip(points, self.plan):
            if plan and plan[0] not in seen:
                seen.add(plan[0])
                if not self.have(plan[0], plan[1]):
                    todo.append((p, plan))
        if not todo:
            return 0
        os.makedirs(self.folder, exist_ok=True)

        def one(item):
            point, (bid, names, eff) = item
            t0 = time.monotonic()
            run_dir = os.path.join(self.folder, f"bed-{bid}")
            settle(self.scene_path, {n: self.file(bid, n) for n in names},
                   set=dict(self.sets, **point), output_dir=run_dir, **run_args)
            wall = time.monotonic() - t0
            with open(os.path.join(self.folder, f"bed-{bid}.json"), "w") as f:
                json.dump({"id": bid, "beds": {n: os.path.basename(self.file(bid, n)) for n in names},
                           "point": point, "scene": bed_scene(eff, names)}, f, indent=1)
            what = []
            for n in names:  # the dem's own figures, from its log (cosim run: logs/<name>.log)
                try:
                    with open(os.path.join(run_dir, "logs", f"{n}.log")) as f:
                        found = SETTLED_RE.findall(f.read())
                except OSError:
                    found = []
                what += [f"{n}: {g} grains in {k} steps, {s} s" for g, k, s in found] or [f"{n}: not reported"]
            return f"bed-{bid} ({json.dumps(point)}): settled {'; '.join(what)}; settle run {wall:.1f} s\n"

        with concurrent.futures.ThreadPoolExecutor(max_workers=max(1, jobs)) as pool:
            lines = list(pool.map(one, todo))
        with open(os.path.join(self.folder, LOG_FILE), "a") as f:
            f.writelines(lines)
        return len(todo)

    def run_sets(self, index, sets):
        """The --set overrides of point `index` (its sets and point merged):
        each settled dem's particles replaced by its bed file."""
        plan = self.plan[index]
        if not plan:
            return sets
        bid, names, _ = plan
        out = dict(sets)
        for n in names:
            prefix = f"processes.{n}.particles"
            for k in [k for k in out if k == prefix or k.startswith(prefix + ".")]:
                del out[k]
            out[prefix] = {"file": self.file(bid, n)}
        return out
