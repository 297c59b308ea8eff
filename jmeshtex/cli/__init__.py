"""The ``jmeshtex`` command line: thin subcommands over the library API."""

from .._extras import needs_methods as _needs_methods  # noqa: F401 (names a missing extra)
from ._main import main as main
