"""Gradient transformations for jmeshtex's parameters, to compose with optax, and a weight average.

:func:`complex_steepest` goes first in an ``optax.chain`` whenever the parameters have complex
leaves (every ``jmeshtex.ops.init_*`` of a tangent-feature layer draws complex weights)::

    optimizer = optax.chain(jmeshtex.optim.complex_steepest(), optax.adam(1e-3))

:func:`flat` runs a transformation on the parameters concatenated into one vector per dtype (the
same updates, a training step that compiles faster); the FL-VAE, FLDM and DGTS trainers wrap their
optimisers in it.

:func:`ema_update` keeps an exponential moving average of the weights beside them (the FL-VAE and
FLDM trainers return it as the model when ``Config.ema_decay > 0``).

Depends on jax and optax only.
"""

from ._complex import complex_steepest as complex_steepest
from ._ema import ema_update as ema_update
from ._flat import flat as flat
