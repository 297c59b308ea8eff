"""Off-screen rendering to PNG (matplotlib Agg): vertex colours, UV textures, scalar and tangent fields."""

# -- public names added by each module below this line --
