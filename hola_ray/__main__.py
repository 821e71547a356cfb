"""`python -m hola_ray COMMAND [ARGS]`: the package's commands (`hola_ray.commands`) and the
experiment's (`python -m hola_ray experiment …`, as `python -m hola_ray.experiment`)."""

from __future__ import annotations

import importlib
import sys

from hola_ray.commands import COMMANDS


def main(argv: list[str] | None = None) -> int:
    argv = sys.argv[1:] if argv is None else argv
    known = {**COMMANDS, "experiment": "a designed comparison of methods over seeds"}
    if not argv or argv[0] in ("-h", "--help") or argv[0] not in known:
        width = max(map(len, known))
        lines = [f"  {name:<{width}}  {what}" for name, what in known.items()]
        print("usage: python -m hola_ray COMMAND [ARGS]\n\ncommands:\n" + "\n".join(lines))
        if argv and argv[0] not in ("-h", "--help"):
            print(f"error: unknown command {argv[0]!r}", file=sys.stderr)
            return 2
        return 0 if argv else 2
    name = argv[0]
    module = "hola_ray.experiment.command" if name == "experiment" else f"hola_ray.commands.{name}"
    sys.argv = [f"python -m hola_ray {name}", *argv[1:]]
    importlib.import_module(module).script()  # exits with the command's code
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
