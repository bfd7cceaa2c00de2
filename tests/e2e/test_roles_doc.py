"""PROTOCOL.md explains the role table; `cosim roles --json` is the table
(proto/roles.c), the coupling contract. Every array of every role and
message appears in the page's table of that role, with its dtype, shape and
coupler field (summed or not), and the page lists no array the table does
not have. Every step/done row names a field; no other row does."""
import json
import os
import re
import subprocess

from common import COSIM, HERE, check, done

doc = open(os.path.join(HERE, "..", "..", "proto", "PROTOCOL.md")).read()
table = json.loads(subprocess.run([COSIM, "roles", "--json"], capture_output=True, text=True,
                                  check=True).stdout)
for role, msgs in table["roles"].items():
    part = doc.split(f"### Role `{role}`")[1].split("###")[0]
    rows = {(m, a): (d, s, f.strip()) for m, a, d, s, f in
            re.findall(r"^\| (\w+) \| `(\w+)` \| (\w+) \[([^\]]*)\] \|([^|]*)\|", part,
                       re.M)}
    listed = set()
    for msg, arrays in msgs.items():
        for a in arrays:
            shape = ",".join(str(x) for x in a["shape"])
            check(("field" in a) == (msg in ("step", "done")),
                  f"role {role}: {msg} {a['name']}: a coupler field on step/done rows only")
            field = (f"`{a['field']}`" + (" (summed)" if a["summed"] else "")
                     if "field" in a else "–")
            got = rows.get((msg, a["name"]))
            check(got == (a["dtype"], shape, field), f"PROTOCOL.md, role {role}: {msg} "
                  f"{a['name']} {a['dtype']} [{shape}] {field} (page: {got})")
            listed.add((msg, a["name"]))
    check(set(rows) == listed, f"role {role}: the page lists {sorted(set(rows) - listed)} "
          f"that the table does not have")
check([m["type"] for m in table["messages"]][:5] == ["hello", "welcome", "ready", "step", "done"],
      "message types in run order")
done()
