"""Kernels that bind the unused positions of the augmentation template: they change nothing."""

from numba import njit


@njit(cache=True, inline="always")
def no_effect(p, po, sc, st, so, u, v, dt, fb, kb, g, dg, fa, ka):
    """An empty inner-effect position: (g, dg, fa, ka) unchanged."""
    return g, dg, fa, ka


@njit(cache=True, inline="always")
def no_capacity(p, po, sc, so):
    """The series position of a law without a series effect (never called)."""
    return 0.0


@njit(cache=True, inline="always")
def no_stick(p, po):
    """A series slider without a stick spring: rigid-plastic (stick displacement 0)."""
    return 0.0


@njit(cache=True, inline="always")
def no_compliance(p, po, f):
    """The slack position of a law without a slack element (never called)."""
    return 0.0, 0.0
