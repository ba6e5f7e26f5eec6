"""The BLAS thread limit of the gap engine's fits."""

from __future__ import annotations

from contextlib import contextmanager

__all__ = ["one_blas_thread"]


@contextmanager
def one_blas_thread():
    """Run the block with the BLAS libraries on one thread (``threadpoolctl``), then restore them.

    The least-squares fits call LAPACK's SVD of a tall, thin Jacobian (a few thousand rows, ~10
    columns) hundreds of times; multithreaded OpenBLAS takes 10-100 ms per call on a shared,
    loaded machine against 0.25 ms on one thread (measured on the 2-core machine: the SVD was 6 of
    14 s of a diagnosis idle and 75 of 114 s under load).
    """
    from threadpoolctl import threadpool_limits

    with threadpool_limits(limits=1, user_api="blas"):
        yield
