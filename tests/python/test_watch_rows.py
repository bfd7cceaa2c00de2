"""cosim watch's bounded series (python/cosim/watch.py Rows): past MAX_ROWS every
other kept row is dropped and the stride doubles; the rows kept are exactly rows
of the input at their row numbers, the last row received is always among them,
the sums cover every row received -- the same whether the rows come one by one
(the bus) or at once (results.h5). And table_key maps bus topics to the
datasets of results.h5."""
import os
import sys

import numpy as np

HERE = os.path.dirname(os.path.abspath(__file__))
sys.path.insert(0, os.path.join(HERE, "..", "e2e"))
from common import check, done  # noqa: E402

from cosim import watch  # noqa: E402

watch.MAX_ROWS = 8  # small, so that the halving happens many times
for n in (0, 1, 5, 8, 9, 17, 100, 1001):
    a = np.c_[np.arange(n), np.arange(n) ** 2.0]
    one_by_one = watch.Rows(["t", "a"])
    for row in a:
        one_by_one.add(row)
    for how, r in (("add", one_by_one), ("of", watch.Rows.of(["t", "a"], a))):
        idx, rows = r.kept()
        check(r.received == n and r.n <= watch.MAX_ROWS, f"{how} {n}: {r.received}, {r.n} kept")
        check(np.array_equal(rows, a[idx]), f"{how} {n}: kept rows are not the input's")
        check(n == 0 or idx[-1] == n - 1, f"{how} {n}: last row not kept ({idx})")
        check(np.allclose(r.sums, a.sum(axis=0)), f"{how} {n}: sums")
        c = watch._chart(r)
        check(c["rows"] == n and len(c["index"]) <= watch.PLOT_POINTS, f"{how} {n}: chart")
check(watch.table_key("coupler.traction", "series") == "coupler/traction", "table_key coupler")
check(watch.table_key("dem.series", "series.wall_forces") == "dem/wall_forces", "table_key dem")
done()
