"""Testing helpers: procedural meshes, hypothesis strategies and the equivariance harness."""

# -- public names added by each module below this line --
