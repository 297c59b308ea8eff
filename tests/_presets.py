"""The smallest method configurations, shared by the tests of several folders (one definition, so
two tests that mean the same tiny model build the same one). Each test adds its own fields with
``.replace(...)``; the presets hold only what their users have in common.
"""

from __future__ import annotations

from jmeshtex import fl, fldm

#: the smallest FL-VAE network: 8 features, 2 heads, 1 block, 8 samples per vertex, a 16-wide
#: decoder (as fields, for the CLI tests' ``--config`` files)
FL_MICRO_NETWORK = dict(features=8, num_heads=2, num_blocks=1, num_samples=8, decoder_features=16)
#: :data:`FL_MICRO_NETWORK` as a config
FL_MICRO = fl.Config(**FL_MICRO_NETWORK)
#: :data:`FL_MICRO` on 10-12-vertex planar meshes of 16-pixel images
FL_MICRO_MESHES = FL_MICRO.replace(min_vertices=10, max_vertices=12, max_image_size=16)
#: the encoder / decoder / loss tests' network: three latent channels, 8 features, 2 heads, 1 block,
#: a 16-wide decoder, the default samples per vertex
FL_SMALL = fl.Config(latent_dim=3, features=8, num_heads=2, num_blocks=1, decoder_features=16)

#: a four-step FL-VAE training run with a checkpoint half-way (the training, resume and data-stream
#: tests' schedule)
FL_SHORT_RUN = dict(
    latent_dim=4, batch_size=2, steps=4, warmup_steps=2, checkpoint_every=2, learning_rate=3e-3
)

#: the smallest FLDM: two latent channels on 40-vertex copies, 4/6-wide blocks, T = 20
FLDM_MICRO = fldm.Config.tiny(
    latent_channels=2,
    copy_vertices=40,
    widths=(4, 6),
    hdim=2,
    knn=5,
    diffusion_steps=20,
    bucket=16,
)
