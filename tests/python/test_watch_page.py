"""`cosim watch` in headless Chromium (python/cosim/watch.py):

1. watching a live stub run (configs/stub_tire.json, long enough to see it go)
   through its output dir, the page's step counter advances while the run is
   live, and at the end (status "final") its last row of every series -- the
   table under each chart and the last point of each uPlot chart -- equals
   results.h5's last row bit for bit, the step counter shows n_steps, the
   shares table has each process and the snapshot picture has loaded;
2. a page opened after the run ended (a new `cosim watch` on the same dir)
   shows the same final state;
3. the server answers GET only: POST is refused (501).
"""
import os
import re
import subprocess
import sys
import time
import urllib.error
import urllib.request

HERE = os.path.dirname(os.path.abspath(__file__))
ROOT = os.path.abspath(os.path.join(HERE, "..", ".."))
sys.path.insert(0, os.path.join(ROOT, "tests", "e2e"))
from common import check, done, scratch  # noqa: E402

import cosim  # noqa: E402
from selenium import webdriver  # noqa: E402
from selenium.webdriver.common.by import By  # noqa: E402

BIN = os.environ.get("COSIM_BIN", os.path.join(ROOT, "build", "bin"))
# stub_tire at dt 1 ms: 24000 steps, ~8 s in Release on an idle machine of stop 35 (longer
# under ASan), 2-3 s on a faster one, where the run was over before the page came up
# (9162, 10556 with 12000 steps; 15490, 24000 and 17022 with 24000): the dem stub sleeps
# STEP_WALL_S per step, so the run lasts >= 9.6 s on any machine; the page comes up 3 s or
# more into the run, polls once a second and must see three values live
T_END_S = 24.0
STEP_WALL_S = 4e-4
SEEN_STEPS = 3        # distinct step counts the page must show during the live run
LIVE_WAIT_S = 60.0    # bounds on each wait (a failure, not a slow machine, hits them)
FINAL_WAIT_S = 60.0
POLL_S = 0.2
CHROME_FLAGS = ["--headless", "--no-sandbox", "--disable-gpu", "--disable-background-networking",
                "--disable-component-update", "--disable-sync", "--no-first-run",
                "--window-size=1400,2400"]


def browser():
    opts = webdriver.ChromeOptions()
    for f in CHROME_FLAGS + [f"--user-data-dir={scratch('watch-chrome-')}"]:
        opts.add_argument(f)
    return webdriver.Chrome(options=opts)


def start_watch(run_dir):
    """`python3 -m cosim watch RUN_DIR --http 127.0.0.1:0`; its URL from the first line."""
    env = dict(os.environ, PYTHONPATH=os.path.join(ROOT, "python"))
    w = subprocess.Popen([sys.executable, "-m", "cosim", "watch", run_dir, "--http",
                          "127.0.0.1:0"], stdout=subprocess.PIPE, text=True, env=env)
    line = w.stdout.readline()
    m = re.search(r"(http://127\.0\.0\.1:\d+/)", line)
    if not m:
        w.kill()
        raise SystemExit(f"cosim watch printed no URL: {line!r}")
    return w, m.group(1)


def text(d, css):
    return d.find_element(By.CSS_SELECTOR, css).text


def wait_for(d, what, until):
    end = time.monotonic() + until
    while time.monotonic() < end:
        if what():
            return True
        time.sleep(POLL_S)
    return False


def check_final(d, run_dir, label):
    """The page's final state against results.h5."""
    ok = wait_for(d, lambda: text(d, "#status") == "final", FINAL_WAIT_S)
    if not check(ok, f"{label}: status final (is '{text(d, '#status')}', "
                 f"error '{text(d, '#error')}')"):
        return
    plots = d.execute_script(
        "const o = {}; for (const [id, w] of Object.entries(window.cosimWatch.plots))"
        " o[id] = {key: w.key, cols: w.plot.series.map(s => s.label),"
        " last: w.plot.data.map(a => a[a.length - 1])}; return o;")
    with cosim.Results(run_dir) as r:
        n_steps = round(r.scene["time"]["end"] / r.scene["time"]["dt"])
        check(text(d, "#step") == str(n_steps), f"{label}: step {text(d, '#step')} != {n_steps}")
        for proc, ds in r.tables():
            key, tab = f"{proc}/{ds}", r.series(proc, ds)
            last = tab.array[-1]
            for c, v in zip(tab.columns, last):
                cell = text(d, f'table.last[data-table="{key}"] td[data-col="{c}"]')
                check(float(cell) == float(v), f"{label}: {key} {c}: page {cell} != h5 {v!r}")
            p = plots.get(key)
            if not check(p is not None, f"{label}: no chart of {key}"):
                continue
            for c, v in zip(p["cols"][1:], p["last"][1:]):
                check(v == float(last[tab.columns.index(c)]),
                      f"{label}: chart {key} {c}: {v!r} != {last[tab.columns.index(c)]!r}")
            check(p["last"][0] == float(tab["t"][-1]), f"{label}: chart {key}: last t")
        for proc in ("fem", "dem"):
            check(d.find_elements(By.CSS_SELECTOR, f'#shares tr[data-process="{proc}"]'),
                  f"{label}: no share of {proc}")
    check(wait_for(d, lambda: d.execute_script(  # drawn by the server on the page's request
        "const i = document.getElementById('snapshot'); return i.complete && i.naturalWidth > 0;"),
        FINAL_WAIT_S), f"{label}: the snapshot picture has not loaded")


def main():
    run_dir = os.path.join(scratch("watch-run-"), "stub_tire")
    log = open(os.path.join(os.path.dirname(run_dir), "run.log"), "w")
    run = subprocess.Popen([os.path.join(BIN, "cosim"), "run",
                            os.path.join(ROOT, "configs", "stub_tire.json"),
                            "--set", f"output.dir={run_dir}", "--set", f"time.end={T_END_S}",
                            "--set", "bus.monitor=tcp://127.0.0.1:0",
                            "--set", f"processes.dem.step_wall={STEP_WALL_S}"],
                           stdout=log, stderr=subprocess.STDOUT)
    watch, url = start_watch(run_dir)
    d = browser()
    try:
        # 1. live: the step counter advances
        d.get(url)
        seen = set()

        def advancing():
            if text(d, "#status") == "live" and text(d, "#step").isdigit():
                seen.add(int(text(d, "#step")))
            return len(seen - {0}) >= SEEN_STEPS
        check(wait_for(d, advancing, LIVE_WAIT_S),
              f"live: the step counter showed {sorted(seen)} (wanted {SEEN_STEPS} values)")
        check(run.wait(timeout=2 * LIVE_WAIT_S) == 0, "the stub run failed")
        check_final(d, run_dir, "live page at the end")
        # 3. GET only
        try:
            urllib.request.urlopen(urllib.request.Request(url + "api/state", data=b"x"))
            check(False, "POST /api/state was answered")
        except urllib.error.HTTPError as e:
            check(e.code == 501, f"POST /api/state: HTTP {e.code}, expected 501")
        # 2. a page opened after the end
        watch.terminate()
        watch.wait()
        watch, url = start_watch(run_dir)
        d.get(url)
        check_final(d, run_dir, "page opened after the end")
    finally:
        d.quit()
        watch.terminate()
        watch.wait()
        if run.poll() is None:
            run.kill()
    done()


if __name__ == "__main__":
    main()
