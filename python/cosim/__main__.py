"""``python3 -m cosim COMMAND ...``: the package's commands (``cosim sweep``
forwards here). Exit codes as ``cosim run``: 0 ok, 1 bad usage or scene,
3 a run failed, 130 interrupted."""
import sys

from .errors import CosimError, RunError

COMMANDS = {"sweep": "cosim sweep SCENE --values KEY.PATH=V1,V2,... --out DIR ..."}


def main(argv):
    if not argv or argv[0] not in COMMANDS:
        what = f"unknown command '{argv[0]}'" if argv else "no command"
        print(f"cosim (python): {what}; commands:\n  " + "\n  ".join(COMMANDS.values()),
              file=sys.stderr)
        return 1
    from . import sweep_cli
    try:
        return sweep_cli.main(argv[1:])
    except KeyboardInterrupt:
        print("cosim sweep: interrupted", file=sys.stderr)
        return 130
    except RunError as e:
        print(f"cosim sweep: {e}", file=sys.stderr)
        return e.returncode if e.returncode not in (None, 0) else 3
    except CosimError as e:
        print(f"cosim sweep: {e}", file=sys.stderr)
        return 1


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
