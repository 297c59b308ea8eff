"""``jmeshtex verify``: run the equivariance registry and print operator × transform errors."""

from __future__ import annotations

import argparse
import pathlib
import sys

from ..io import atomic_write
from ._common import add_common


def register(sub: argparse._SubParsersAction) -> None:
    p = sub.add_parser(
        "verify",
        help="check equivariance of every registered operator numerically",
        description=(
            "Run every registered operator under its transforms (rigid motions, gauge changes, "
            "relabelling, exact folds, smooth isometries) in float64 and float32 and print the "
            "maximum relative error, the bound, the observed convergence order and the verdict."
        ),
    )
    p.add_argument("--json", type=pathlib.Path, help="also write the results as JSON to this path")
    p.add_argument(
        "--only", nargs="+", metavar="NAME", help="operators to check (default: all selected)"
    )
    p.add_argument(
        "--module",
        nargs="+",
        metavar="MOD",
        default=[],
        help=(
            "import these modules (e.g. pkg.entries; the working directory is searched first) and "
            "check only the operators their register(...) calls add"
        ),
    )
    p.add_argument(
        "--all",
        action="store_true",
        help="with --module: check the built-in operators too",
    )
    p.add_argument(
        "--transforms", nargs="+", metavar="T", help="transforms to check (default: all declared)"
    )
    p.add_argument("--dtype", choices=["both", "float64", "float32"], default="both")
    p.add_argument("--list", action="store_true", help="list registered operators and transforms")
    add_common(p, out=None)
    p.set_defaults(func=_run)


def _run(args: argparse.Namespace) -> int:
    import jax

    jax.config.update("jax_enable_x64", True)
    import jax.numpy as jnp

    from .. import testing

    own = _import_modules(args.module)
    if args.all or args.only or not args.module:
        testing.load_entries()
    _check_only(args.only)
    if args.list:
        _print_registry()
        return 0
    dtypes = {
        "both": (jnp.float64, jnp.float32),
        "float64": (jnp.float64,),
        "float32": (jnp.float32,),
    }[args.dtype]
    names = args.only or (own if args.module and not args.all else list(testing.REGISTRY))
    results = _run_checks(names, dtypes, args)
    print(testing.format_table(results))
    failed = [r for r in results if r.passed is False]
    print(
        f"\n{len(results)} checks: {sum(r.passed is True for r in results)} passed, "
        f"{len(failed)} failed, {sum(r.passed is None for r in results)} reported"
    )
    if args.json:
        atomic_write(args.json, testing.to_json(results))
        print(f"wrote {args.json}")
    return 1 if failed else 0


def _import_modules(modules: list[str]) -> list[str]:
    """Import the ``--module`` modules (the working directory searched first); returns the
    operators they register (by the import, or earlier by code of the same modules)."""
    import importlib

    from .. import testing
    from .._errors import InputError

    if modules and str(pathlib.Path.cwd()) not in sys.path:
        sys.path.insert(0, str(pathlib.Path.cwd()))  # as `python -m` does: the user's own folder
    before = set(testing.REGISTRY)
    for module in modules:
        try:
            importlib.import_module(module)
        except ImportError as e:
            raise InputError(f"--module {module}: cannot import it ({e})") from e
    own = [
        n
        for n, e in testing.REGISTRY.items()
        if n not in before or getattr(e.apply, "__module__", None) in modules
    ]
    if modules and not own:
        raise InputError(
            f"--module {' '.join(modules)}: the import registered no operator; a module adds "
            "one with jmeshtex.testing.register(Entry(...)) at import time"
        )
    return own


def _check_only(only: list[str] | None) -> None:
    """Refuse ``--only`` operators that are not registered."""
    from .. import testing
    from .._errors import InputError

    unknown = [n for n in only or () if n not in testing.REGISTRY]
    if unknown:
        raise InputError(
            f"not registered: {', '.join(unknown)}; registered operators: "
            f"{', '.join(testing.REGISTRY)} (an operator of your own is registered by importing "
            "its module: --module pkg.mod)"
        )


def _print_registry() -> None:
    """``--list``: the registered operators with their transforms, then the transforms."""
    from .. import testing

    for name, e in testing.REGISTRY.items():
        print(f"{name:32s} {e.group:9s} {', '.join(e.transforms)}")
    print("\ntransforms:")
    for name, t in testing.CATALOGUE.items():
        print(f"  {name:17s} {'exact ' if t.exact else 'smooth'} {t.doc}")


def _run_checks(names: list[str], dtypes: tuple, args: argparse.Namespace) -> list:
    """Run the registry's checks of ``names`` in ``dtypes`` with a progress bar on stderr
    (unknown ``--transforms`` refused)."""
    from tqdm import tqdm

    from .. import testing
    from .._errors import InputError
    from .._memory_maps import release_if_near_limit
    from ..testing import transforms_of

    transforms = args.transforms
    bogus = [t for t in transforms or () if t not in testing.CATALOGUE]
    if bogus:
        raise InputError(
            f"--transforms: unknown {', '.join(bogus)}; known: {', '.join(testing.CATALOGUE)}"
        )
    total = sum(
        len(
            [t for t in transforms_of(testing.REGISTRY[n]) if transforms is None or t in transforms]
        )
        * len(dtypes)
        for n in names
        if n in testing.REGISTRY
    )
    bar = tqdm(
        total=total,
        desc="verify",
        unit="check",
        file=sys.stderr,
        disable=True if args.quiet else None,
    )

    def progress(msg: str) -> None:
        # a whole-registry run compiles past vm.max_map_count unless JAX's caches are released
        release_if_near_limit()
        bar.set_postfix_str(msg[:60])
        bar.update(1)

    results = testing.run_registry(
        names, dtypes=dtypes, seed=args.seed, transforms=transforms, progress=progress
    )
    bar.close()
    return results
