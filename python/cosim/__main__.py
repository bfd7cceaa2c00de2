"""``python3 -m cosim COMMAND ...``: the package's commands (``cosim sweep``
and ``cosim watch`` forward here). Exit codes as ``cosim run``: 0 ok, 1 bad
usage or scene, 3 a run failed, 130 interrupted."""
import sys

from .errors import CosimError, RunError

COMMANDS = {"sweep": "cosim sweep SCENE --values KEY.PATH=V1,V2,... --out DIR ...",
            "watch": "cosim watch RUN_DIR|ENDPOINT [--http 127.0.0.1:8080] ..."}


def main(argv):
    if not argv or argv[0] not in COMMANDS:
        what = f"unknown command '{argv[0]}'" if argv else "no command"
        print(f"cosim (python): {what}; commands:\n  " + "\n  ".join(COMMANDS.values()),
              file=sys.stderr)
        return 1
    cmd = argv[0]
    if cmd == "watch":
        from . import watch as module
    else:
        from . import sweep_cli as module
    try:
        return module.main(argv[1:])
    except KeyboardInterrupt:
        print(f"cosim {cmd}: interrupted", file=sys.stderr)
        return 130
    except RunError as e:
        print(f"cosim {cmd}: {e}", file=sys.stderr)
        return e.returncode if e.returncode not in (None, 0) else 3
    except CosimError as e:
        print(f"cosim {cmd}: {e}", file=sys.stderr)
        return 1


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
