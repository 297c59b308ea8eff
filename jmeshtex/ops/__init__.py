"""Pure, jit/vmap/grad-safe operators over padded neighbourhood arrays (parameters passed explicitly)."""

# -- public names added by each module below this line (one `from ._x import y as y` per name) --
