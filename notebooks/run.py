"""Execute the notebooks and commit them with their outputs, so the figures show on the repository page.

Usage: ``python notebooks/run.py [NAME ...]`` (default: every notebook here). Each notebook runs top
to bottom in a fresh kernel with the tiny settings CI uses (``JMESHTEX_NOTEBOOK_TINY=1``; ``--full``
runs the full ones), its files written to a temporary folder, and is written back in place
(atomically) with its outputs and a stamp, ``metadata.jmeshtex.source_sha256``: the digest of its
code cells. ``tests/test_notebooks.py`` fails when a notebook's code no longer matches its stamp (the
outputs are stale: run this script) or a code cell has no outputs.
"""

from __future__ import annotations

import argparse
import hashlib
import os
import pathlib
import sys
import tempfile
import time

HERE = pathlib.Path(__file__).resolve().parent


def source_digest(nb: dict) -> str:
    """SHA-256 of the notebook's code cells' sources, in order (outputs and markdown excluded)."""
    h = hashlib.sha256()
    for cell in nb["cells"]:
        if cell["cell_type"] == "code":
            src = cell["source"]
            h.update(("".join(src) if isinstance(src, list) else src).encode())
            h.update(b"\0")
    return h.hexdigest()


def execute(path: pathlib.Path, *, tiny: bool = True, timeout: int = 900) -> float:
    """Run ``path`` in a fresh kernel and write it back with outputs and its stamp; seconds taken."""
    import nbformat
    from nbclient import NotebookClient

    nb = nbformat.read(path, as_version=4)
    t0 = time.perf_counter()
    with tempfile.TemporaryDirectory(prefix="jmeshtex-notebook-") as tmp:
        os.environ["JMESHTEX_NOTEBOOK_TINY"] = "1" if tiny else "0"
        os.environ["JMESHTEX_NOTEBOOK_OUT"] = tmp
        NotebookClient(
            nb, timeout=timeout, kernel_name="python3", resources={"metadata": {"path": tmp}}
        ).execute()
    nb.metadata["jmeshtex"] = {"source_sha256": source_digest(nb), "tiny": tiny}
    tmp_path = path.with_suffix(".ipynb.tmp")
    nbformat.write(nb, tmp_path)
    os.replace(tmp_path, path)
    return time.perf_counter() - t0


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("names", nargs="*", help="notebook names (default: all)")
    parser.add_argument("--full", action="store_true", help="the full settings, not the tiny ones")
    args = parser.parse_args(argv)
    paths = [HERE / f"{n.removesuffix('.ipynb')}.ipynb" for n in args.names] or sorted(
        HERE.glob("*.ipynb")
    )
    for path in paths:
        seconds = execute(path, tiny=not args.full)
        print(f"{path.name}: {seconds:.0f} s", flush=True)
    return 0


if __name__ == "__main__":
    sys.exit(main())
