"""Convert FL-VAE / FLDM / DGTS model files and FL / FLDM checkpoint folders written before format 2, once.

Format 2 stores every config field in a model file's header and takes a checkpoint's config
fingerprint from ``ConfigBase.fingerprint()`` (every field but the resumable ones). Earlier files
relied on readers that filled in missing fields (``fl`` ``LEGACY_VALUES``, the fingerprints'
``_ADDED_FIELDS`` / ``added``); those readers are gone, so this script writes the values they
filled in into the files themselves:

- an FL-VAE model file (``.npz``, kind ``jmeshtex.fl.Model``, version 1): fields it lacks get
  ``token="ring_mean"``, ``log_objective="vertex"`` (what the version-1 reader assumed) and today's
  defaults for the rest; the header's version becomes 2;
- an FLDM or DGTS model folder or its ``model.npz`` (version 1): fields it lacks get today's
  defaults (what the version-1 reader gave them); version 2;
- a checkpoint folder of ``fl.train`` / ``fldm.train`` (``.jmeshtex-checkpoints.json`` in it): each
  step's stored fingerprint gets the config fields the old fingerprint left out at their default
  (fl ``ema_decay``; fldm ``invariants``, ``schedule_shift``, ``phase_sync``, ``flat_spread``), and
  the folder's record of file sizes and hashes is updated, so the run resumes under format 2.

Usage (from the repository root; files are rewritten in place, atomically, and a file already in
format 2 is left as it is)::

    python studies/convert_to_format_2.py jmeshtex/fl/weights/fl_vae.npz jmeshtex/fldm/weights/spot
    python studies/convert_to_format_2.py jmeshtex/dgts/weights/knobs.npz benchmarks/results/dgts_*_model
    python studies/convert_to_format_2.py runs/fldm_spot_coherent3k/train runs/fldm_spot_coherent3k/models/step_01000
"""

from __future__ import annotations

import argparse
import hashlib
import json
import pathlib
import sys

from jmeshtex import dgts, fl, fldm
from jmeshtex.io import atomic_write, read_arrays, save_model

HEADER = "__jmeshtex_model__"
RECORD = ".jmeshtex-checkpoints.json"
#: what the version-1 FL reader filled into a stored config that lacked these fields
FL_LEGACY = {"token": "ring_mean", "log_objective": "vertex"}
#: config fields the version-1 fingerprints left out while at these values
FL_FINGERPRINT_ADDED = {"ema_decay": 0.0}
FLDM_FINGERPRINT_ADDED = {
    "invariants": False,
    "schedule_shift": 1.0,
    "phase_sync": "none",
    "flat_spread": 0.02,
}


def convert_model(path: pathlib.Path) -> str:
    """Rewrite one model file of version 1 as version 2; returns what was done."""
    if path.is_dir():
        path = path / "model.npz"
    arrays = read_arrays(path)
    header = json.loads(str(arrays.pop(HEADER)))
    if header["format_version"] == 2:
        return f"{path}: already format 2"
    if header["format_version"] != 1:
        raise SystemExit(f"{path}: format version {header['format_version']}, expected 1")
    kind, stored = header["kind"], dict(header["config"])
    if kind == "jmeshtex.fl.Model":
        cls, filled = fl.Config, {k: v for k, v in FL_LEGACY.items() if k not in stored}
    elif kind == "jmeshtex.fldm.Model":
        cls, filled = fldm.Config, {}
    elif kind == "jmeshtex.dgts.Model":
        cls, filled = dgts.Config, {}
    else:
        raise SystemExit(f"{path}: a {kind!r}, not an FL-VAE, FLDM or DGTS model")
    defaults = cls().to_dict()
    filled.update({k: defaults[k] for k in defaults if k not in stored and k not in filled})
    config = cls.from_dict({**stored, **filled}).to_dict()  # validated
    save_model(
        path,
        kind=kind,
        params=arrays,
        config=config,
        extra=header.get("extra") or None,
        format_version=2,
    )
    return f"{path}: format 1 -> 2, filled in {filled}"


def _files(folder: pathlib.Path) -> dict[str, list]:
    out = {}
    for f in sorted(folder.rglob("*")):
        if f.is_file():
            out[f.relative_to(folder).as_posix()] = [
                f.stat().st_size,
                hashlib.sha256(f.read_bytes()).hexdigest(),
            ]
    return out


def convert_checkpoints(folder: pathlib.Path) -> list[str]:
    """Add the fields the version-1 fingerprints left out to every step's fingerprint."""
    record = json.loads((folder / RECORD).read_text())
    done = []
    for step in sorted(record["steps"], key=int):
        meta_path = folder / step / "meta" / "metadata"
        meta = json.loads(meta_path.read_text())
        config = meta.get("fingerprint", {}).get("config")
        if config is None:
            done.append(f"{meta_path}: no config fingerprint, left as it is")
            continue
        added = FLDM_FINGERPRINT_ADDED if "latent_channels" in config else FL_FINGERPRINT_ADDED
        missing = {k: v for k, v in added.items() if k not in config}
        if not missing:
            done.append(f"{meta_path}: already complete")
            continue
        meta["fingerprint"]["config"] = dict(sorted({**config, **missing}.items()))
        atomic_write(meta_path, json.dumps(meta).encode())
        record["steps"][step]["files"] = _files(folder / step)
        done.append(f"{meta_path}: added {missing}")
    atomic_write(folder / RECORD, json.dumps(record, sort_keys=True) + "\n")
    return done


def main(argv: list[str] | None = None) -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("paths", nargs="+", type=pathlib.Path, help="model files/folders, checkpoints")
    for path in ap.parse_args(argv).paths:
        if (path / RECORD).is_file():
            print("\n".join(convert_checkpoints(path)))
        else:
            print(convert_model(path))


if __name__ == "__main__":
    main(sys.argv[1:])
