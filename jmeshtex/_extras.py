"""Optional dependencies: the lean install (``pip install jmeshtex``) carries what ``jmeshtex.ops``,
``jmeshtex.optim`` and the neighbourhood pytrees need (flax, for ``jmeshtex.nn``, is the ``[nn]``
extra); every other package checks its extra when imported and names it in one line when something
is missing.

A package checks with an import, first in its ``__init__``
(``from .._extras import needs_geometry as _needs_geometry``): the name is computed on access
(:func:`__getattr__`), which calls :func:`require_extra`.
"""

from __future__ import annotations

import importlib.util
import sys

from ._errors import MissingExtraError as MissingExtraError

#: the import names each extra provides (the pip names are in pyproject.toml)
EXTRAS: dict[str, tuple[str, ...]] = {
    "geometry": ("scipy", "igl", "trimesh", "robust_laplacian", "PIL"),
    "render": ("scipy", "igl", "trimesh", "robust_laplacian", "PIL", "matplotlib"),
    "metrics": ("skimage",),
    "nn": ("flax",),
    "methods": (
        "flax",
        "scipy",
        "igl",
        "trimesh",
        "robust_laplacian",
        "PIL",
        "matplotlib",
        "skimage",
        "orbax",
        "xatlas",
        "tqdm",
    ),
}
EXTRAS["testing"] = EXTRAS["methods"] + ("hypothesis",)


def _available(module: str) -> bool:
    try:
        return importlib.util.find_spec(module) is not None
    except (ImportError, ValueError):
        return False


def require_extra(package: str, extra: str) -> None:
    """Raise :class:`MissingExtraError` naming ``jmeshtex[extra]`` if one of its modules is missing.

    Args:
      package: the importing package, e.g. ``"jmeshtex.geometry"`` (for the message).
      extra: a key of :data:`EXTRAS`.

    Example:
      >>> require_extra("jmeshtex.ops", "metrics")  # scikit-image installed: nothing happens
    """
    missing = [m for m in EXTRAS[extra] if not _available(m)]
    if missing:
        raise MissingExtraError(
            f"{package} needs the optional dependencies of jmeshtex[{extra}] (missing: "
            f"{', '.join(missing)}): pip install 'jmeshtex[{extra}]'"
        )


def __getattr__(name: str) -> bool:
    """``needs_<extra>``: :func:`require_extra` for that extra, then ``True``."""
    extra = name.removeprefix("needs_")
    if name.startswith("needs_") and extra in EXTRAS:
        importer = sys._getframe(1).f_globals.get("__name__", "jmeshtex")  # the package importing
        require_extra(importer, extra)
        return True
    raise AttributeError(f"module {__name__!r} has no attribute {name!r}")
