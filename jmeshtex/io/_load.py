"""Read meshes (OBJ/PLY/OFF/GLB, through trimesh) and texture images into host-side records.

trimesh reads the files with ``process=False`` (no merging, no cleaning; it still triangulates
polygons and stores one vertex per distinct (position, UV) pair); the only changes jmeshtex makes
on top are the documented seam merge of :func:`load_mesh` and, for files with polygon faces, a
:class:`~jmeshtex.MeshRepairWarning` saying how many were split (or, with ``strict=True``, a
:class:`~jmeshtex.NonTriangleFaceError`).
"""

from __future__ import annotations

import os
import pathlib
import re
import warnings

import numpy as np

from .._errors import MeshIOError, MeshRepairWarning, NonTriangleFaceError
from .._mesh import Mesh
from .._mesh_arrays import coincident_vertex_map
from .._types import Float
from ._read import check_input_file, check_memory
from ._save import _unique_rows, mesh_suffix


def _readable_file(path: str | os.PathLike, what: str) -> pathlib.Path:
    """``path`` if it is a readable regular file of bounded size (:func:`check_input_file`)."""
    return check_input_file(path, what)


def _open_image(path: pathlib.Path, what: str):
    """A decoded PIL image of ``path``, refused before decoding when its pixels exceed the budget."""
    from PIL import Image

    with warnings.catch_warnings():
        warnings.simplefilter("ignore")  # e.g. PIL's DecompressionBombWarning: the budget decides
        limit, Image.MAX_IMAGE_PIXELS = Image.MAX_IMAGE_PIXELS, None
        try:
            image = Image.open(path)
        finally:
            Image.MAX_IMAGE_PIXELS = limit
        try:
            width, height = image.size
            check_memory(
                4.0 * width * height * max(1, len(image.getbands())),
                f"{what} {path} ({width} x {height} pixels)",
            )
            image.load()
        except BaseException:
            image.close()
            raise
    return image


def _image_to_float(image) -> np.ndarray:
    """A PIL image as float32 ``[H, W, C]`` in [0, 1] (C = 1, 2, 3 or 4), row 0 at the top."""
    mode = image.mode
    if mode in ("P", "PA"):
        image = image.convert("RGBA" if (mode == "PA" or "transparency" in image.info) else "RGB")
    elif mode == "1":
        image = image.convert("L")
    elif mode not in ("L", "LA", "RGB", "RGBA", "I", "F") and not mode.startswith("I;16"):
        image = image.convert("RGBA" if "A" in mode else "RGB")  # CMYK, YCbCr, LAB, HSV, ...
    arr = np.asarray(image)
    if mode.startswith("I;16") or image.mode == "I":
        out = arr.astype(np.float32) / np.float32(65535)
    elif image.mode == "F":
        out = arr.astype(np.float32)
    else:
        out = arr.astype(np.float32) / np.float32(255)
    if out.ndim == 2:
        out = out[:, :, None]
    if out.size and not (np.isfinite(out).all() and out.min() >= 0 and out.max() <= 1):
        finite = out[np.isfinite(out)]
        bad = int(out.size - finite.size)
        span = f"values from {finite.min():.3g} to {finite.max():.3g}" if finite.size else ""
        nonfinite = f"{bad} non-finite texel value(s)" if bad else ""
        raise MeshIOError(
            f"the {image.mode} image has {', '.join(x for x in (nonfinite, span) if x)}; texels "
            "must lie in [0, 1]. Fix: save it as an 8- or 16-bit image, or scale float data to "
            "[0, 1]"
        )
    return np.ascontiguousarray(out)


def load_texture(path: str | os.PathLike) -> Float[np.ndarray, "H W C"]:
    """Read an image file as a float32 texture ``[H, W, C]`` in [0, 1], row 0 at the top (v = 1).

    8-bit images are divided by 255, 16-bit ones by 65535; palette images become RGB(A), grey
    images keep one channel (two with alpha).

    Args:
      path: a PNG, JPEG, BMP, TGA, TIFF or WebP file.

    Returns:
      ``[H, W, C]`` float32.

    Raises:
      MeshIOError: missing, not a regular file, larger than the read cap or the memory budget,
        unreadable, not an image, or with texels outside [0, 1] (float images: NaN, inf, 1e6).

    Example:
      >>> import numpy as np, pathlib, tempfile
      >>> from jmeshtex.io import save_png
      >>> path = pathlib.Path(tempfile.mkdtemp()) / "t.png"
      >>> save_png(np.zeros((4, 8, 3)), path)
      >>> t = load_texture(path)
      >>> t.shape, t.dtype
      ((4, 8, 3), dtype('float32'))
    """
    path = _readable_file(path, "texture")
    try:
        with _open_image(path, "texture") as image:
            return _image_to_float(image)
    except MeshIOError as err:
        if str(err).startswith("cannot read"):
            raise
        raise MeshIOError(f"cannot read texture {path}: {err}") from err
    except Exception as err:  # PIL raises OSError, UnidentifiedImageError, SyntaxError, ...
        raise MeshIOError(f"cannot read texture {path}: {err}") from err


_BOM = b"\xef\xbb\xbf"


def _obj_index(token: str, count: int, kind: str, path: pathlib.Path, number: int, line: str):
    """Check one OBJ index (1-based, or negative = relative); a typed error names the line."""
    try:
        value = int(token)
    except ValueError:
        raise MeshIOError(
            f"cannot read mesh {path}: line {number} has a bad {kind} index {token!r} "
            f"({line.strip()[:80]!r})"
        ) from None
    if value == 0:
        raise MeshIOError(
            f"cannot read mesh {path}: line {number} uses {kind} index 0 ({line.strip()[:80]!r}); "
            "OBJ indices start at 1. Fix: the file looks 0-based: add 1 to every index"
        )
    if not -count <= value <= count:
        raise MeshIOError(
            f"cannot read mesh {path}: line {number} uses {kind} index {value}, but the file has "
            f"{count} {kind} line(s) before it ({line.strip()[:80]!r})"
        )


def _check_obj_text(path: pathlib.Path, text: str) -> set[str]:
    """Refuse bad ``v`` lines and face indices (0-based, out of range, also ``vt``); warn about
    faces with fewer than 3 corners and missing or bad MTL/textures. Returns the referenced files
    that may not be read (trimesh's resolver refuses them)."""
    counts = {"v": 0, "vt": 0, "vn": 0}
    short = 0
    for number, line in enumerate(text.splitlines(), 1):
        fields = line.split("#", 1)[0].split()
        if not fields:
            continue
        head = fields[0]
        if head == "v" and len(fields) < 4:
            raise MeshIOError(
                f"cannot read mesh {path}: line {number} is a vertex with {len(fields) - 1} "
                f"coordinate{'s' if len(fields) != 2 else ''} ({line.strip()!r}); OBJ vertices "
                "need x y z"
            )
        if head in counts:
            counts[head] += 1
        elif head == "f":
            if len(fields) < 4:
                short += 1
            for corner in fields[1:]:
                parts = corner.split("/")
                for part, kind in zip(parts, ("v", "vt", "vn"), strict=False):
                    if part:
                        _obj_index(part, counts[kind], kind, path, number, line)
    if short:
        warnings.warn(
            f"load_mesh: {path.name}: dropped {short} face line(s) with fewer than 3 corners",
            MeshRepairWarning,
            stacklevel=4,
        )
    refused: set[str] = set()
    for name in re.findall(r"^[ \t]*mtllib[ \t]+([^\n#]+?)[ \t]*$", text, flags=re.MULTILINE):
        mtl = path.parent / name.strip()
        if not mtl.exists():
            _dropped(path, f"its material file {mtl.name} is missing ({mtl})")
            continue
        try:
            check_input_file(mtl, "material file")
            mtl_text = mtl.read_text(encoding="utf-8", errors="replace")
        except (MeshIOError, OSError) as err:
            refused.add(name.strip())
            _dropped(path, f"its material file {mtl} cannot be read ({err})")
            continue
        maps = re.findall(
            r"^[ \t]*map_[A-Za-z]+[ \t]+([^\n#]+?)[ \t]*$", mtl_text, flags=re.MULTILINE
        )
        for entry in maps:
            image = path.parent / entry.split()[-1]
            if not image.exists():
                _dropped(path, f"the texture {image.name} named by {mtl.name} is missing ({image})")
                continue
            try:
                check_input_file(image, "texture")
                with _open_image(image, "texture") as img:
                    _image_to_float(img)
            except Exception as err:  # PIL raises OSError, UnidentifiedImageError, SyntaxError
                refused.add(entry.split()[-1])
                _dropped(path, f"the texture {image} named by {mtl.name} cannot be read ({err})")
    return refused


def referenced_files(path: str | os.PathLike) -> list[pathlib.Path]:
    """The files a mesh file makes jmeshtex read besides itself: an OBJ's MTL files and the
    texture images they name (existing ones only).

    Example:
      >>> referenced_files("no-such.obj")
      []
    """
    path = pathlib.Path(path)
    if path.suffix.lower() != ".obj" or not path.is_file():
        return []
    try:
        text = path.read_text(encoding="utf-8", errors="replace")
    except OSError:
        return []
    out = []
    for name in re.findall(r"^[ \t]*mtllib[ \t]+([^\n#]+?)[ \t]*$", text, flags=re.MULTILINE):
        mtl = path.parent / name.strip()
        if not mtl.is_file():
            continue
        out.append(mtl)
        try:
            mtl_text = mtl.read_text(encoding="utf-8", errors="replace")
        except OSError:
            continue
        for entry in re.findall(
            r"^[ \t]*map_[A-Za-z]+[ \t]+([^\n#]+?)[ \t]*$", mtl_text, flags=re.MULTILINE
        ):
            image = path.parent / entry.split()[-1]
            if image.exists():
                out.append(image)
    return out


def _resolver(path: pathlib.Path, refused: set[str]):
    """trimesh's file resolver for ``path``'s folder that reads only checked regular files."""
    import trimesh

    class _CheckedResolver(trimesh.resolvers.FilePathResolver):
        def get(self, name):
            if name in refused:
                raise MeshIOError(f"{name} refused")
            check_input_file(path.parent / name, "file referenced by the mesh")
            return super().get(name)

    return _CheckedResolver(str(path))


def _check_off(path: pathlib.Path, data: bytes) -> None:
    """Refuse an OFF file whose header counts do not match its body (lying or truncated)."""
    lines = [
        line.split("#")[0].split() for line in data.decode("ascii", errors="replace").splitlines()
    ]
    tokens = [t for t in lines if t]
    if not tokens:
        raise MeshIOError(f"cannot read mesh {path}: the file is empty")
    head = tokens[0][1:] if tokens[0][0].upper().endswith("OFF") else tokens[0]
    body = tokens[1:]
    if not head:
        if not body:
            raise MeshIOError(f"cannot read mesh {path}: no counts line after OFF")
        head, body = body[0], body[1:]
    try:
        nv, nf = int(head[0]), int(head[1])
    except (ValueError, IndexError):
        raise MeshIOError(
            f"cannot read mesh {path}: bad OFF counts line {' '.join(head)!r}"
        ) from None
    if nv < 0 or nf < 0 or len(body) != nv + nf:
        raise MeshIOError(
            f"cannot read mesh {path}: the header declares {nv} vertices and {nf} faces "
            f"({nv + nf} lines) but the body has {len(body)} lines; the file is truncated or its "
            "header is wrong"
        )
    for number, fields in enumerate(body[nv:], 1):
        try:
            corners = int(fields[0])
        except ValueError:
            raise MeshIOError(f"cannot read mesh {path}: face {number} is {fields!r}") from None
        if corners < 3 or len(fields) < 1 + corners:
            raise MeshIOError(
                f"cannot read mesh {path}: face {number} ({' '.join(fields)[:80]!r}) lists "
                f"{len(fields) - 1} of {corners} corners; faces need 3 or more"
            )


def _dropped(path: pathlib.Path, what: str) -> None:
    warnings.warn(
        f"load_mesh: {path.name}: {what}; the mesh is loaded without it (pass texture= to give "
        "one)",
        MeshRepairWarning,
        stacklevel=4,
    )


def _check_ascii_ply(path: pathlib.Path, data: bytes) -> None:
    """Refuse an ASCII PLY whose header's element counts do not match its body."""
    end = data.find(b"end_header")
    if end < 0:
        return
    header = data[:end].decode("ascii", errors="replace").splitlines()
    if not any(line.split()[:2] == ["format", "ascii"] for line in header if line.split()):
        return
    counts = []
    for line in header:
        fields = line.split()
        if len(fields) == 3 and fields[0] == "element":
            try:
                counts.append((fields[1], int(fields[2])))
            except ValueError:
                raise MeshIOError(f"cannot read mesh {path}: bad header line {line!r}") from None
    newline = data.find(b"\n", end)
    body = data[newline + 1 :].decode("ascii", errors="replace") if newline >= 0 else ""
    lines = sum(1 for line in body.splitlines() if line.strip())
    declared = sum(n for _, n in counts)
    if lines != declared:
        described = ", ".join(f"{n} {name}" for name, n in counts)
        raise MeshIOError(
            f"cannot read mesh {path}: the header declares {described} ({declared} lines) but the "
            f"body has {lines} lines; the file is truncated or its header is wrong"
        )


def _trimesh_mesh(path: pathlib.Path):
    import io

    import trimesh

    suffix = path.suffix.lower()
    source: str | io.BytesIO = str(path)
    resolver = None
    if suffix in (".obj", ".ply", ".off"):
        try:
            data = path.read_bytes()
        except OSError as err:
            raise MeshIOError(f"cannot read mesh {path}: {err.strerror or err}") from err
        if suffix == ".obj":
            if data.startswith(_BOM):  # trimesh would read "\ufeffv" as an unknown keyword
                data = data[len(_BOM) :]
            data = data.replace(b"\t", b" ")  # trimesh splits OBJ fields on spaces only
            refused = _check_obj_text(path, data.decode("utf-8", errors="replace"))
            source = io.BytesIO(data)
            resolver = _resolver(path, refused)
        elif suffix == ".off":
            _check_off(path, data)
        elif data.startswith(b"ply"):
            _check_ascii_ply(path, data)
    try:
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")  # trimesh's internal deprecation noise
            scene = trimesh.load_scene(
                source, file_type=suffix[1:], process=False, resolver=resolver
            )
            parts = [g for g in scene.dump() if isinstance(g, trimesh.Trimesh) and len(g.faces)]
            if len(parts) > 1:
                loaded = trimesh.util.concatenate(parts)
            else:
                loaded = parts[0] if parts else None
    except Exception as err:  # trimesh raises anything from ValueError to IndexError on bad files
        raise MeshIOError(f"cannot read mesh {path}: {type(err).__name__}: {err}") from err
    if loaded is None:
        raise MeshIOError(f"cannot read mesh {path}: the file contains no triangles")
    return loaded


def _face_sizes(loaded, path: pathlib.Path) -> np.ndarray:
    """Corners of every face record in the file, in file order (empty if the file cannot tell).

    trimesh fan-triangulates polygons without saying so: an ``n``-gon becomes ``n - 2`` triangles.
    OBJ ``f`` lines and OFF face lines are counted from the text, PLY faces from trimesh's raw
    elements; glTF primitives are triangles by definition.
    """
    suffix = path.suffix.lower()
    try:
        if suffix == ".obj":
            text = path.read_text(errors="replace")
            lines = re.findall(r"^[ \t]*f[ \t]+([^\n#]*)", text, flags=re.MULTILINE)
            return np.array([len(line.split()) for line in lines], np.int64)
        if suffix == ".off":
            lines = [
                line.split("#")[0].split() for line in path.read_text(errors="replace").splitlines()
            ]
            tokens = [t for t in lines if t]
            head = tokens[0][1:] if tokens[0][0].upper().endswith("OFF") else tokens[0]
            body = tokens[1:]
            if not head:
                head, body = body[0], body[1:]
            nv, nf = int(head[0]), int(head[1])
            return np.array([int(t[0]) for t in body[nv : nv + nf]], np.int64)
        if suffix == ".ply":
            data = loaded.metadata.get("_ply_raw", {}).get("face", {}).get("data")
            if data is None:
                return np.zeros(0, np.int64)
            names = data.keys() if isinstance(data, dict) else (data.dtype.names or ())
            field = next((n for n in ("vertex_indices", "vertex_index") if n in names), None)
            if field is None:
                return np.zeros(0, np.int64)
            lists = data[field]
            if lists.dtype.names:  # binary: (count, indices) records
                return np.asarray(lists[lists.dtype.names[0]], np.int64).reshape(-1)
            if lists.dtype == object:  # ragged ASCII lists
                return np.array([len(x) for x in lists], np.int64)
            return np.full(len(lists), lists.shape[1] if lists.ndim == 2 else 3, np.int64)
    except (ValueError, IndexError, TypeError, AttributeError, KeyError, OSError):
        pass  # trimesh read the file; a layout this count does not know is no reason to fail
    return np.zeros(0, np.int64)


def _check_polygons(loaded, path: pathlib.Path, *, strict: bool) -> None:
    """Warn (or, ``strict``, raise) when the file's polygon faces were split into triangles."""
    sizes = _face_sizes(loaded, path)
    polygons = np.nonzero(sizes > 3)[0]
    if polygons.size == 0:
        return
    corners = " or ".join(map(str, sorted(set(sizes[polygons].tolist()))))
    triangles = int((sizes[polygons] - 2).sum())
    faces = f"{polygons.size} polygon face{'s' if polygons.size > 1 else ''} ({corners} corners)"
    if strict:
        raise NonTriangleFaceError(
            f"cannot read mesh {path} with strict=True: {faces} among its {len(sizes)} faces; "
            "polygons at file faces",
            indices=polygons,
        )
    warnings.warn(
        f"load_mesh: {path.name}: split {faces} into {triangles} triangles "
        "(pass strict=True to refuse polygons)",
        MeshRepairWarning,
        stacklevel=3,
    )


def _lookup_rows(table: np.ndarray, query: np.ndarray) -> np.ndarray:
    """For each row of ``query`` the lowest index of an exactly equal row of ``table``, or -1."""
    _, inverse = _unique_rows(np.concatenate([table, query]))
    first = np.full(inverse.max() + 1, -1)
    first[inverse[: len(table)][::-1]] = np.arange(len(table))[::-1]
    return first[inverse[len(table) :]]


def _raw_vertex_colors(loaded, path: pathlib.Path):
    """Positions and colours as stored in a PLY/OBJ file, for textured meshes.

    trimesh keeps either UVs or vertex colours in its visuals, so for a mesh with both the colours
    are read from the raw PLY elements or the OBJ ``v x y z r g b`` lines and matched by position.
    """
    suffix = path.suffix.lower()
    if suffix == ".ply":
        data = loaded.metadata.get("_ply_raw", {}).get("vertex", {}).get("data")
        names = getattr(getattr(data, "dtype", None), "names", None) or ()
        if not {"x", "y", "z", "red", "green", "blue"} <= set(names):
            return None
        channels = ["red", "green", "blue"] + (["alpha"] if "alpha" in names else [])
        positions = np.stack([data[k] for k in "xyz"], axis=1).astype(np.float64)
        return positions, np.stack([data[k] for k in channels], axis=1)
    if suffix == ".obj":
        text = path.read_text(errors="replace")
        lines = re.findall(r"^v[ \t]+([^\n#]*)", text, flags=re.MULTILINE)
        if not lines or len(lines[0].split()) not in (6, 7):
            return None
        width = len(lines[0].split())
        tokens = " ".join(lines).split()
        if len(tokens) != width * len(lines):  # mixed rows: give up rather than guess
            return None
        try:
            values = np.array(tokens, dtype=np.float64).reshape(-1, width)
        except ValueError:
            return None
        return values[:, :3], values[:, 3:6]
    return None


def _is_placeholder(image) -> bool:
    """trimesh invents a uniform 2×2 RGBA image (``color_image``) for UVs without a texture."""
    if image.format is not None or image.size != (2, 2) or image.mode != "RGBA":
        return False
    pixels = np.asarray(image).reshape(4, 4)
    return bool((pixels == pixels[0]).all())


def _visual_attributes(loaded, path: pathlib.Path):
    """(uv per stored vertex or None, texture or None, vertex colours or None) from trimesh."""
    import trimesh

    n_vertices = len(loaded.vertices)
    uv = texture = colors = None
    visual = loaded.visual
    if isinstance(visual, trimesh.visual.TextureVisuals):
        if visual.uv is not None and len(visual.uv) == n_vertices:
            uv = np.array(visual.uv, dtype=np.float64)
        material = visual.material
        image = getattr(material, "image", None)
        if image is None:
            image = getattr(material, "baseColorTexture", None)
        if image is not None and not _is_placeholder(image):
            try:
                texture = _image_to_float(image)
            except Exception as err:  # a texture trimesh read but cannot be decoded or is bad
                _dropped(path, f"its texture cannot be used ({err})")
        raw = _raw_vertex_colors(loaded, path)
        if raw is not None:
            match = _lookup_rows(raw[0], np.asarray(loaded.vertices, dtype=np.float64))
            if np.all(match >= 0):
                colors = raw[1][match]
    elif getattr(visual, "kind", None) == "vertex":
        colors = np.asarray(visual.vertex_colors)
        raw = _raw_vertex_colors(loaded, path)  # trimesh turns NaN colours into black
        if raw is not None and raw[1].dtype.kind == "f" and not np.isfinite(raw[1]).all():
            colors = np.asarray(raw[1], np.float64)
    if colors is not None:
        colors = np.asarray(colors)
        if colors.dtype.kind == "f" and not np.isfinite(colors).all():
            rows = np.nonzero(~np.isfinite(colors).all(axis=1))[0]
            raise MeshIOError(
                f"cannot read mesh {path}: {rows.size} vertex colour(s) are NaN or infinite "
                f"(first at vertex {int(rows[0])}). Fix: give every vertex a finite colour"
            )
        if colors.dtype != np.uint8:  # OBJ colours are floats in [0, 1]
            colors = np.round(np.clip(colors.astype(np.float64), 0, 1) * 255).astype(np.uint8)
        if colors.shape[1] == 4 and np.all(colors[:, 3] == 255):
            colors = colors[:, :3]  # fully opaque: RGB
        colors = colors.astype(np.float32) / np.float32(255)
    return uv, texture, colors


def load_mesh(
    path: str | os.PathLike,
    *,
    merge_seams: bool = True,
    texture: str | os.PathLike | None = None,
    strict: bool = False,
) -> Mesh:
    """Read an OBJ, PLY, OFF or GLB file into a :class:`~jmeshtex.Mesh`.

    Files store one vertex per (position, UV) pair, so textured meshes are split along UV seams.
    With ``merge_seams`` (the default) vertices with exactly equal coordinates are merged into one
    (lowest stored index first, in stored order), so geometry sees the closed surface, while
    ``split_faces`` / ``split_to_merged`` keep the stored indexing and ``uv`` stays per corner
    (``uv[f, k] = stored_uv[split_faces[f, k]]``). Exact equality is deliberate: seam copies repeat
    the same numbers, and a tolerance would depend on scale and could weld distinct vertices.
    Coincident vertices whose merge would pinch the surface (two parts touching at a point or along
    an edge) are kept apart, as in :func:`~jmeshtex.geometry.prepare_mesh`. Polygon faces (quads,
    n-gons) are fan-triangulated, an ``n``-gon into ``n - 2`` triangles, with a
    :class:`~jmeshtex.MeshRepairWarning` that says how many. Nothing is validated here: pass the
    result to :func:`~jmeshtex.geometry.prepare_mesh` or :func:`~jmeshtex.geometry.validate_mesh`.

    Args:
      path: mesh file; the format follows the suffix (``.obj``, ``.ply``, ``.off``, ``.glb``).
        Materials and textures referenced by the file are read from its folder.
      merge_seams: merge exactly coincident vertices (see above); False keeps the stored vertices.
      texture: an image to use as ``Mesh.texture`` instead of the one the file references (for
        OBJs shipped without a material file).
      strict: refuse polygon faces (raise) instead of splitting them into triangles with a warning.

    Returns:
      A :class:`~jmeshtex.Mesh`: float64 vertices, int64 faces, per-corner ``uv`` and a float32
      ``texture`` ([H, W, C], row 0 = top = v 1) where present, float32 ``vertex_colors`` (RGB, or
      RGBA if any alpha is below 1), ``name`` = the file's stem.

    Raises:
      MeshIOError: missing, unreadable, unsupported or triangle-free files, bad textures, OBJ
        vertices with fewer than 3 coordinates, ASCII PLY files whose header counts lie.
      NonTriangleFaceError: ``strict=True`` and the file has polygon faces (``err.indices`` are
        their positions among the file's faces).

    Warns:
      MeshRepairWarning: polygon faces were split into triangles; an OBJ's material file or the
        texture it names is missing or unreadable (the message names the file).

    Example:
      >>> import pathlib, tempfile, warnings
      >>> from jmeshtex import MeshRepairWarning
      >>> path = pathlib.Path(tempfile.mkdtemp()) / "quad.obj"
      >>> _ = path.write_text("v 0 0 0\\nv 1 0 0\\nv 1 1 0\\nv 0 1 0\\nf 1 2 3 4\\n")
      >>> with warnings.catch_warnings(record=True) as caught:
      ...     warnings.simplefilter("always", MeshRepairWarning)
      ...     m = load_mesh(path)
      >>> m.num_vertices, m.num_faces, m.name
      (4, 2, 'quad')
      >>> print(caught[0].message)
      load_mesh: quad.obj: split 1 polygon face (4 corners) into 2 triangles (pass strict=True to refuse polygons)
    """
    path = _readable_file(path, "mesh")
    mesh_suffix(path, "read mesh", fix="convert it (e.g. with trimesh or Blender)")
    loaded = _trimesh_mesh(path)
    _check_polygons(loaded, path, strict=strict)
    vertices = np.array(loaded.vertices, dtype=np.float64)
    stored_faces = np.array(loaded.faces, dtype=np.int64)
    if stored_faces.min() < 0 or stored_faces.max() >= len(vertices):
        raise MeshIOError(
            f"cannot read mesh {path}: face indices outside the {len(vertices)} vertices"
        )
    uv, image, colors = _visual_attributes(loaded, path)
    if texture is not None:
        image = load_texture(texture)

    rep = np.arange(len(vertices))
    if merge_seams:
        finite = np.isfinite(vertices).all(axis=1)
        if finite.all():  # NaN rows are never equal anyway; validation reports them later
            rep, _ = coincident_vertex_map(vertices, stored_faces)
    keep = rep == np.arange(len(vertices))
    if keep.all():
        faces, split_faces, split_to_merged = stored_faces, None, None
        merged_vertices = vertices
    else:
        new_id = np.cumsum(keep) - 1
        split_to_merged = new_id[rep]
        split_faces = stored_faces
        faces = split_to_merged[stored_faces]
        merged_vertices = vertices[keep]
        colors = None if colors is None else colors[keep]
    return Mesh(
        vertices=merged_vertices,
        faces=faces,
        uv=None if uv is None else uv[stored_faces],
        texture=image,
        vertex_colors=colors,
        split_faces=split_faces,
        split_to_merged=split_to_merged,
        name=path.stem,
    )
