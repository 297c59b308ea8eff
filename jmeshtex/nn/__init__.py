"""Thin flax modules that only create parameters and call :mod:`jmeshtex.ops`."""

# -- public names added by each module below this line --
from ._face_conv import FaceConvStack as FaceConvStack
from ._texel import TexelConv as TexelConv
