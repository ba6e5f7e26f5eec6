"""The BLAS thread limit of the package's least-squares fits (calibration optimum, gap engine,
rubber polish, building output-error fits)."""

from __future__ import annotations

from contextlib import contextmanager

__all__ = ["one_blas_thread"]


@contextmanager
def one_blas_thread():
    """Run the block with the BLAS libraries on one thread (``threadpoolctl``), then restore them.

    scipy's least squares (``trf``) calls LAPACK's SVD of a tall, thin Jacobian (a few thousand
    rows, ~10 columns) at every iteration; multithreaded OpenBLAS spends 10-100 ms per call
    waking and waiting for its threads when the cores are shared, against 0.3 ms on one thread.
    """
    from threadpoolctl import threadpool_limits

    with threadpool_limits(limits=1, user_api="blas"):
        yield
