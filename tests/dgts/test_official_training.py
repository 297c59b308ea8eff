"""Training-step parity with the official DGTS code (amirhertz/geometric-textures @087c967).

``official/dgts_official_train.npz`` holds one official training iteration (2 critic + 3
generator updates) at each of two levels, recorded from the official ``Trainer`` run unchanged
(``official/README.md``: the command, the driver, every array). Fed the same weights (through
the official-weights converter), training meshes, noise and gradient-penalty ``α``, jmeshtex's
training step must give the official losses, gradients, updated weights and Adam moments, and its
level chaining (frozen level 0, midpoint subdivision, ×2, level-1 noise, the reconstruction from
``z*``) the official level-1 inputs.

The official run uses the official ``Options`` except a smaller network (5 layers of width 8, so
the fixture stays small; the full default network's forward pass is proven by
``test_official_parity.py``); :data:`CONFIG` is ``Config()`` with those widths, so changing a
training default (update counts, Adam betas, learning rate, γ, penalty weight) breaks this test.
"""

from __future__ import annotations

import functools
import json
import pathlib

import jax
import jax.numpy as jnp
import numpy as np
import pytest

from jmeshtex.dgts import Config
from jmeshtex.dgts._official import official_level_params, official_level_state
from jmeshtex.dgts._train import (
    _initial_params,
    _level_state,
    critic_loss,
    generator_loss,
    level_batch,
    train_chunk,
)
from jmeshtex.dgts.core import discriminator, generator_level, hierarchy_geometry

FIXTURE = pathlib.Path(__file__).parent / "official" / "dgts_official_train.npz"

#: the official run's options (``TrainOption(num_layers=5, start_nf=8, min_nf=8, max_nf=8)``)
CONFIG = Config(num_layers=5, start_features=8, min_features=8, max_features=8, official_axes=True)

#: float32 parity bound (STYLE.md: float32 ~1e-5 relative), relative to the largest entry of each
#: quantity (a network's gradients, weights, moments; a mesh's coordinates)
RTOL = 1e-5

D, G = 2, 3


@pytest.fixture(scope="module")
def off() -> dict[str, np.ndarray]:
    with np.load(FIXTURE, allow_pickle=False) as data:
        return {k: data[k] for k in data.files}


def _net(off, prefix: str, level: int, *, critic: bool):
    state = {k[len(prefix) + 1 :]: v for k, v in off.items() if k.startswith(prefix + "/")}
    return jax.tree.map(jnp.asarray, official_level_params(state, level, critic=critic))


def _normed_bias(name: str) -> bool:
    """A bias followed by an instance norm (every layer's but the last: ``layers.<i>.0.conv``).

    Such a bias adds one constant per channel to every face (before or after the max over edges
    alike), which the norm subtracts again: it changes no output, so its gradient is zero in exact
    arithmetic and float32 rounding (~1e-7 of the largest gradient) in both implementations. Adam
    divides by ``√v̂ + 1e-8``, turning that noise into updates of ``O(lr)`` with arbitrary signs, so
    after one step these entries differ by up to ~3e-3 (measured) between any two
    implementations; they are compared through the outputs instead (they change none).
    """
    return name.endswith(".0.conv.bias")


def _official_layout(
    tree, level: int, *, square: bool = False, normed_biases: bool = True
) -> np.ndarray:
    """A level's parameters (or gradients, moments) in the official layout, one flat vector."""
    state = official_level_state(tree, level)
    names = [k for k in sorted(state) if normed_biases or not _normed_bias(k)]
    flat = np.concatenate([state[k].ravel() for k in names])
    return np.abs(flat) if square else flat


def _official_flat(off, prefix: str, *, normed_biases: bool = True) -> np.ndarray:
    names = sorted(
        k for k in off if k.startswith(prefix + "/") and (normed_biases or not _normed_bias(k))
    )
    assert names, prefix
    return np.concatenate([off[k].ravel() for k in names])


def _rel(ours, official) -> float:
    ours, official = np.asarray(ours, np.float64), np.asarray(official, np.float64)
    assert ours.shape == official.shape
    return float(np.abs(ours - official).max() / np.abs(official).max())


class Level:
    """Level ``L``'s inputs in jmeshtex's vertex order, built from the official draws."""

    def __init__(self, off, L: int):
        self.L = L
        faces0 = off["template_faces"]
        V0 = len(off["template"])
        geos, faces = hierarchy_geometry(faces0, V0, 2)
        self.geos, self.nbhd = geos[: L + 1], geos[L].nbhd
        # jmeshtex's level-1 vertex j is official vertex perm[j] (midpoints in another order)
        where = {tuple(e): j for j, e in enumerate(off["level1_edge"])}
        edges = np.asarray(geos[0].edge_vertices)
        perm1 = np.concatenate([np.arange(V0), [where[tuple(sorted(e))] for e in edges]])
        self.perm = np.arange(V0) if L == 0 else perm1
        self.faces = faces[L]
        self.real = off[f"l{L}_real"][self.perm]
        fresh = [  # the fakes of every update, then (level 0) the reconstructions
            np.stack([off[f"l{L}_{u}_z{lv}"] for u in ("d0", "d1", "g0", "g1", "g2")])
            for lv in range(L + 1)
        ]
        if L == 0:
            fresh[0] = np.concatenate([fresh[0], [off[f"l0_g{k}_recz0"] for k in range(G)]])
        else:
            fresh[1] = fresh[1][:, perm1]
            for k in range(G):  # z* at level 0, zero noise at level 1, in every generator update
                np.testing.assert_array_equal(off[f"l1_g{k}_recz0"], off["l1_g0_recz0"])
                assert off[f"l1_g{k}_recz1"] == 0
        self.z_star = off["l1_g0_recz0"]
        self.alpha = np.array([[off[f"l{L}_d0_alpha"], off[f"l{L}_d1_alpha"]]], np.float32)
        frozen = () if L == 0 else (_net(off, "l0_g_final", 0, critic=False),)
        self.batch = level_batch(
            frozen,
            self.geos,
            jnp.asarray(off["template"])[None],
            jnp.asarray(self.z_star)[None],
            jnp.asarray(self.real)[None],
            jax.random.key(0),  # unused: every draw is given
            config=CONFIG,
            chunk=1,
            noise=[jnp.asarray(z) for z in fresh],
            alpha=self.alpha,
        )

    def official(self, off, name: str) -> np.ndarray:
        """An official level-``L`` vertex array in jmeshtex's vertex order."""
        return off[f"l{self.L}_{name}"][self.perm]


@pytest.fixture(scope="module", params=[0, 1], ids=["level0", "level1"])
def level(request, off) -> Level:
    return Level(off, request.param)


@functools.partial(jax.jit, static_argnames=("config",))
def _critic_grad(d, fake, real, alpha, nbhd, config):
    return jax.value_and_grad(critic_loss, has_aux=True)(d, fake, real, alpha, nbhd, config=config)


@functools.partial(jax.jit, static_argnames=("config",))
def _generator_grad(g, d, base, z, rec_base, rec_z, real, nbhd, config):
    return jax.value_and_grad(generator_loss, has_aux=True)(
        g, d, base, z, rec_base, rec_z, real, nbhd, config=config
    )


@jax.jit
def _produce(g, base, z, nbhd):
    return base + generator_level(g, base, nbhd, z, y_sign=CONFIG.y_sign)


def test_fixture_documents_how_it_was_made(off):
    readme = json.loads(str(off["README"]))
    assert {"source", "options", "meshes", "weights", "updates"} <= set(readme)
    assert "087c967" in readme["source"]
    # the defaults the test relies on: the official TrainOption's, and CONFIG = Config() but widths
    changed = {k for k, v in CONFIG.to_dict().items() if Config().to_dict()[k] != v}
    assert changed == {
        "start_features",
        "min_features",
        "max_features",
        "num_layers",
        "official_axes",
    }


def test_fresh_noise_and_alpha_are_drawn_as_the_official_ones(off):
    """The draws the parity tests replay: vertex noise ``0.1·N(0, 1)`` (``noise_amplitude``; the
    official draws' std is 0.1 within sampling error) and ``α ~ U(0, 1)``, one per critic update."""
    z = np.concatenate([off[k].ravel() for k in off if "_z" in k and off[k].ndim == 2])
    assert len(z) > 2000 and abs(z.std() / 0.1 - 1) < 0.05 and abs(z.mean()) < 0.01
    assert CONFIG.noise_amplitude == 0.1
    lv = Level(off, 0)
    b = level_batch(
        (),
        lv.geos,
        jnp.asarray(off["template"])[None],
        jnp.asarray(lv.z_star)[None],
        jnp.asarray(lv.real)[None],
        jax.random.key(1),
        config=CONFIG,
        chunk=20,
    )
    for ours in (np.asarray(b.fake_noise), np.asarray(b.rec_noise)):
        assert abs(ours.std() / CONFIG.noise_amplitude - 1) < 0.05
    a = np.asarray(b.alpha)
    assert a.shape == (20, D) and a.min() >= 0 and a.max() <= 1 and abs(a.mean() - 0.5) < 0.15


def test_level_chaining_gives_the_official_level_inputs(off, level):
    """Frozen level 0 on fresh noise, subdivision, ×2 (the fakes' inputs), and the reconstruction
    from ``z*`` then zero noise: jmeshtex's level batch equals the official generator inputs."""
    b, L = level.batch, level.L
    if L == 1:  # the official level-1 connectivity is jmeshtex's, relabelled
        inv = np.argsort(level.perm)
        ours = {tuple(np.roll(f, -np.argmin(f))) for f in level.faces}
        theirs = {tuple(np.roll(f, -np.argmin(f))) for f in inv[off["l1_real_faces"]]}
        assert ours == theirs
    for k, u in enumerate(("d0", "d1", "g0", "g1", "g2")):
        assert _rel(b.fake_base[0, k], level.official(off, f"{u}_fake_base")) < RTOL, u
        np.testing.assert_array_equal(b.fake_noise[0, k], level.official(off, f"{u}_z{L}"))
    for k in range(G):
        assert _rel(b.rec_base[0, k], level.official(off, f"g{k}_rec_base")) < RTOL
    np.testing.assert_array_equal(b.alpha, level.alpha)
    np.testing.assert_array_equal(b.real[0], level.real)


def test_level_one_starts_from_level_zero_as_the_official_dup(off):
    """Equal widths: level 1's generator and critic start from level 0's trained ones."""
    g0, d0 = _net(off, "l0_g_final", 0, critic=False), _net(off, "l0_d_final", 0, critic=True)
    g1, d1 = _initial_params(CONFIG, 1, jax.random.key(0), [g0], [d0])
    assert _rel(_official_layout(g1, 1), _official_flat(off, "l1_g_init")) == 0
    assert _rel(_official_layout(d1, 1), _official_flat(off, "l1_d_init")) == 0


def test_each_update_gives_the_official_losses_and_gradients(off, level):
    """Each of the 5 updates, from the official weights before it: the critic's scores on the real
    and the fake mesh, the gradient penalty at the official α, the generator's adversarial score
    and reconstruction MSE, the generated meshes, and every parameter gradient."""
    b, L, nb = level.batch, level.L, level.nbhd
    g = _net(off, f"l{L}_g_init", L, critic=False)
    for k in range(D):
        p = f"l{L}_d{k}"
        d = _net(off, f"{p}_before", L, critic=True)
        fake = _produce(g, b.fake_base[0, k], b.fake_noise[0, k], nb)
        assert _rel(fake, level.official(off, f"d{k}_fake")) < RTOL
        (loss, aux), grad = _critic_grad(d, fake, b.real[0], b.alpha[0, k], nb, CONFIG)
        s_real, s_fake, gp = (float(x) for x in aux)
        assert _rel(s_real, off[f"{p}_real_score"]) < RTOL
        assert _rel(s_fake, off[f"{p}_fake_score"]) < RTOL
        assert _rel(gp, off[f"{p}_gp"]) < RTOL
        assert _rel(_official_layout(grad, L), _official_flat(off, f"{p}_grad")) < RTOL
    d = _net(off, f"l{L}_d_final", L, critic=True)  # the critic after its 2 updates
    for k in range(G):
        p = f"l{L}_g{k}"
        g = _net(off, f"{p}_before", L, critic=False)
        args = (b.fake_base[0, D + k], b.fake_noise[0, D + k], b.rec_base[0, k], b.rec_noise[0, k])
        assert _rel(_produce(g, args[0], args[1], nb), level.official(off, f"g{k}_fake")) < RTOL
        assert _rel(_produce(g, args[2], args[3], nb), level.official(off, f"g{k}_rec")) < RTOL
        (loss, aux), grad = _generator_grad(g, d, *args, b.real[0], nb, CONFIG)
        adv, mse = (float(x) for x in aux)
        assert _rel(-adv, off[f"{p}_adv_score"]) < RTOL
        assert _rel(mse, off[f"{p}_rec_mse"]) < RTOL
        assert _rel(_official_layout(grad, L), _official_flat(off, f"{p}_grad")) < RTOL


def _adam_moments(opt_state, params, level: int) -> tuple[np.ndarray, np.ndarray, int]:
    """``(m, v, count)`` of a level's flat Adam state, in the official layout."""
    adam = opt_state.inner[0]
    leaves, treedef = jax.tree.flatten(params)
    cuts = np.cumsum([0] + [x.size for x in leaves])
    out = []
    for moment in (adam.mu["float32"], adam.nu["float32"]):
        parts = [
            moment[a:b].reshape(x.shape)
            for a, b, x in zip(cuts[:-1], cuts[1:], leaves, strict=True)
        ]
        out.append(jax.tree.unflatten(treedef, parts))
    m = _official_layout(out[0], level)
    v = _official_layout(out[1], level, square=True)
    return m, v, int(adam.count)


def test_one_training_step_gives_the_official_weights_and_adam_moments(off, level):
    """``train_chunk`` (the step ``dgts.train`` runs) for one step from the official weights: the
    critic and the generator after their 2 + 3 updates, Adam's moments and step counts, and the
    step's reported losses (the last critic and generator update's)."""
    L = level.L
    g = _net(off, f"l{L}_g_init", L, critic=False)
    d = _net(off, f"l{L}_d_init", L, critic=True)
    state = _level_state(CONFIG, L, g, d)
    g, d, opt, losses = train_chunk(
        g, d, state["opt"], level.nbhd, level.batch, jnp.int32(1), config=CONFIG
    )
    b, nb = level.batch, level.nbhd
    g_off = _net(off, f"l{L}_g_final", L, critic=False)
    d_off = _net(off, f"l{L}_d_final", L, critic=True)
    for ours, theirs in ((g, g_off), (d, d_off)):  # every weight but the normed biases
        assert (
            _rel(
                _official_layout(ours, L, normed_biases=False),
                _official_layout(theirs, L, normed_biases=False),
            )
            < RTOL
        )
    # the updated networks compute the official updated networks' outputs (normed biases included)
    fake = _produce(g, b.fake_base[0, 0], b.fake_noise[0, 0], nb)
    assert (
        _rel(
            fake - b.fake_base[0, 0],
            _produce(g_off, b.fake_base[0, 0], b.fake_noise[0, 0], nb) - b.fake_base[0, 0],
        )
        < RTOL
    )
    assert _rel(discriminator(d, b.real[0], nb), discriminator(d_off, b.real[0], nb)) < RTOL
    assert _rel(discriminator(d, fake, nb), discriminator(d_off, fake, nb)) < RTOL
    for net, params, updates in (("g", g, G), ("d", d, D)):
        m, v, count = _adam_moments(getattr(opt, net), params, L)
        assert count == updates
        assert _rel(m, _official_flat(off, f"l{L}_{net}_adam_m")) < RTOL
        assert _rel(v, _official_flat(off, f"l{L}_{net}_adam_v")) < RTOL
    expected = {
        "d_real": off[f"l{L}_d1_real_score"],
        "d_fake": off[f"l{L}_d1_fake_score"],
        "penalty": off[f"l{L}_d1_gp"],
        "g_adv": -off[f"l{L}_g2_adv_score"],
        "g_rec": off[f"l{L}_g2_rec_mse"],
    }
    for name, value in expected.items():
        assert _rel(losses[name][0], value) < RTOL, name


@pytest.mark.parametrize("L", [0, 1])
def test_adam_on_the_official_gradients_gives_the_official_weights(off, L):
    """jmeshtex's optimiser (``_optimizer``: Adam, lr 5e-4, betas (0.5, 0.99), the flat wrapper)
    fed the official gradients, update after update, gives the official weights after every
    update and the official moments: every entry, the normed biases included (same inputs)."""
    from jmeshtex.dgts._train import _optimizer

    for net, updates in (("d", D), ("g", G)):
        critic = net == "d"
        params = _net(off, f"l{L}_{net}_init", L, critic=critic)
        opt = _optimizer(CONFIG, updates)
        state = opt.init(params)
        for k in range(updates):
            p = f"l{L}_{net}{k}"
            assert _rel(_official_layout(params, L), _official_flat(off, f"{p}_before")) < RTOL
            grads = _net(off, f"{p}_grad", L, critic=critic)
            with jax.numpy_dtype_promotion("standard"):  # optax mixes int counters and floats
                step, state = opt.update(grads, state, params)
            params = jax.tree.map(lambda w, u: w + u, params, step)
        assert _rel(_official_layout(params, L), _official_flat(off, f"l{L}_{net}_final")) < RTOL
        m, v, count = _adam_moments(state, params, L)
        assert count == updates
        assert _rel(m, _official_flat(off, f"l{L}_{net}_adam_m")) < RTOL
        assert _rel(v, _official_flat(off, f"l{L}_{net}_adam_v")) < RTOL


def test_the_learning_rate_halves_after_every_500_iterations_as_the_official_loop():
    """``training.py``: ``lr_decay_every = 500``, ``decay`` (``ExponentialLR(0.5).step()``) after
    iterations 499, 999, …, so iteration ``i`` runs at ``5e-4 · 0.5^⌊i/500⌋`` for all its updates.
    Adam on a constant gradient moves by the learning rate itself (``m̂/√v̂ = 1``)."""
    from jmeshtex.dgts._train import _optimizer

    for updates in (D, G):
        opt = _optimizer(CONFIG, updates)
        iterations = 1002
        x = jnp.zeros(2, jnp.float32)

        def body(carry, _, opt=opt):
            x, state = carry
            with jax.numpy_dtype_promotion("standard"):
                step, state = opt.update(jnp.ones_like(x), state, x)
            return (x + step, state), -step[0]

        _, lr = jax.lax.scan(body, (x, opt.init(x)), None, length=iterations * updates)
        i = np.arange(iterations * updates) // updates  # the official iteration of each update
        np.testing.assert_allclose(np.asarray(lr), 5e-4 * 0.5 ** (i // 500), rtol=RTOL)
