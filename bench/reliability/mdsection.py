"""Writes one "## " section of a markdown results file, keeping the others
(several benchmarks share bench/results/reliability.md)."""
import os


def write_section(path, title, body, head="# Reliability"):
    """Replaces (or appends) the section `## title` of the file at path."""
    text = open(path).read() if os.path.exists(path) else head + "\n"
    parts = text.split("\n## ")
    new = f"{title}\n\n{body.strip()}\n"
    for i in range(1, len(parts)):
        if parts[i].split("\n", 1)[0].strip() == title:
            parts[i] = new
            break
    else:
        parts[-1] = parts[-1].rstrip("\n") + "\n"
        parts.append(new)
    with open(path, "w") as f:
        f.write("\n## ".join(parts).rstrip("\n") + "\n")
