"""Equivariance registrations of each method (imported by :func:`jmeshtex.testing.load_entries`)."""
