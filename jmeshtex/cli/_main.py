"""Entry point of the ``jmeshtex`` console script.

Each subcommand lives in its own module ``jmeshtex/cli/_<name>.py`` that defines
``register(subparsers)`` (adds its parser and sets ``func``) and is listed in ``_SUBCOMMANDS``.
Errors derived from :class:`jmeshtex.JmeshtexError` are printed as one clear message (no traceback)
with exit status 2.
"""

from __future__ import annotations

import argparse
import contextlib
import importlib
import os
import sys

from .._errors import JmeshtexError

# subcommand modules, in the order `jmeshtex --help` lists them
_SUBCOMMANDS: list[str] = [
    "_verify",
    "_demo",
    "_info",
    "_meshmatch",
    "_dgts",
    "_surfacecnn",
    "_fl",
    "_fldm",
]


def build_parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(
        prog="jmeshtex",
        description="Learn and transfer textures on triangle meshes (JAX).",
    )
    parser.add_argument("--version", action="store_true", help="print the version and exit")
    sub = parser.add_subparsers(dest="command", metavar="COMMAND")
    for name in _SUBCOMMANDS:
        importlib.import_module(f"{__package__}.{name}").register(sub)
    return parser


def main(argv: list[str] | None = None) -> int:
    parser = build_parser()
    args = parser.parse_args(argv)
    if args.version:
        from .. import __version__

        print(f"jmeshtex {__version__}")
        return 0
    if not getattr(args, "func", None):
        parser.print_help()
        return 1
    from ..io import protect_reads, unprotect_all
    from ._output import release_all

    rc = 1
    protect_reads()  # no output may replace a file this command read
    try:
        rc = int(args.func(args) or 0)
    except JmeshtexError as err:
        print(f"jmeshtex {args.command}: error: {err}", file=sys.stderr)
        rc = 2
    except MemoryError:
        print(
            f"jmeshtex {args.command}: error: out of memory; use a smaller mesh, image or size",
            file=sys.stderr,
        )
        rc = 2
    except KeyboardInterrupt:
        print(f"jmeshtex {args.command}: interrupted", file=sys.stderr)
        rc = 130
    except BrokenPipeError:
        # the reader of stdout went away (`jmeshtex info ... | head`): not an error of ours
        with contextlib.suppress(OSError):
            devnull = os.open(os.devnull, os.O_WRONLY)
            os.dup2(devnull, sys.stdout.fileno())
        rc = 141
    finally:
        release_all(failed=rc != 0)
        unprotect_all()
    return rc


if __name__ == "__main__":
    sys.exit(main())
