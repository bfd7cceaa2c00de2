#!/usr/bin/python3
"""A screenshot of the `cosim watch` page at the end of a run, in headless Chromium
(Debian: chromium chromium-driver python3-selenium):

    python/examples/watch_screenshot.py RUN_DIR OUT.png

watches RUN_DIR (a live run or an ended one) until the page shows the final state,
then saves the whole page. bench/results/watch.png is this on configs/default.json:

    cosim run configs/default.json --set output.dir=/tmp/watch-runs/default &
    python/examples/watch_screenshot.py /tmp/watch-runs/default bench/results/watch.png
"""
import re
import shutil
import subprocess
import sys
import tempfile
import time

from selenium import webdriver
from selenium.webdriver.common.by import By

FINAL_WAIT_S = 600.0     # the longest run this waits for
PAGE_WIDTH_PX = 1500
SETTLE_S = 1.5           # after "final": the snapshot picture and charts are drawn
FLAGS = ["--headless", "--no-sandbox", "--disable-gpu", "--disable-background-networking",
         "--disable-component-update", "--disable-sync", "--no-first-run"]


def main(run_dir, out):
    w = subprocess.Popen([sys.executable, "-m", "cosim", "watch", run_dir, "--http",
                          "127.0.0.1:0"], stdout=subprocess.PIPE, text=True)
    url = re.search(r"http://\S+/", w.stdout.readline()).group(0)
    profile = tempfile.mkdtemp(prefix="watch-chrome-")
    opts = webdriver.ChromeOptions()
    for f in FLAGS + [f"--user-data-dir={profile}",
                      f"--window-size={PAGE_WIDTH_PX},1200"]:
        opts.add_argument(f)
    d = webdriver.Chrome(options=opts)
    try:
        d.get(url)
        end = time.monotonic() + FINAL_WAIT_S
        while d.find_element(By.ID, "status").text != "final":
            if time.monotonic() > end:
                raise SystemExit(f"{run_dir}: no final state after {FINAL_WAIT_S:g} s")
            time.sleep(0.5)
        time.sleep(SETTLE_S)
        height = d.execute_script("return document.body.scrollHeight")
        d.set_window_size(PAGE_WIDTH_PX, height + 40)
        time.sleep(0.5)
        d.save_screenshot(out)
    finally:
        d.quit()
        w.terminate()
        shutil.rmtree(profile, ignore_errors=True)
    print(f"{out}: the page of {run_dir} at its end")


if __name__ == "__main__":
    if len(sys.argv) != 3:
        sys.exit(__doc__)
    main(*sys.argv[1:])
