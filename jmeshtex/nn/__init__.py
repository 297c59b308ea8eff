"""Thin flax modules that only create parameters and call :mod:`jmeshtex.ops` (``jmeshtex[nn]``)."""

from .._extras import needs_nn as _needs_nn  # noqa: F401 (names a missing extra)
from ._complex import FRN as FRN
from ._complex import ComplexAttention as ComplexAttention
from ._complex import ComplexDense as ComplexDense
from ._complex import VNNonlinearity as VNNonlinearity
from ._complex import VNTransformerBlock as VNTransformerBlock
from ._face_conv import FaceConvStack as FaceConvStack
from ._field_conv import FieldConv as FieldConv
from ._field_conv import FieldConvEmb as FieldConvEmb
from ._texel import TexelConv as TexelConv
