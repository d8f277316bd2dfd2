"""The Newmark predictor and update of the generalized-alpha recurrence, written once.

The update is linear, so the same two kernels advance the state of a run and each column of
its sensitivities. The step coefficients travel as two small arrays,
``pc = (h, cqa, cqg, cva, cvg, bh2, gh)`` and ``upd = (ga, gan, ggn)``
(``morphlab.solve.scheme.StepCoefficients``)::

    q_hat = q_n + h v_n + cqa a_n + cqg g_n,      q_{n+1} = q_hat + bh2 a_{n+1}
    v_hat = v_n + cva a_n + cvg g_n,              v_{n+1} = v_hat + gh a_{n+1}
    g_{n+1} = ga a_{n+1} + gan a_n + ggn g_n

(``docs/theory.md`` §5). Every argument is a 1-D array of one width; the outputs are written
into the arrays passed last.
"""

from ._jit import kernel


@kernel
def predict(pc, q, v, a, g, qh, vh):
    """The predictors ``q_hat``, ``v_hat`` into ``qh``, ``vh``."""
    h, cqa, cqg, cva, cvg = pc[0], pc[1], pc[2], pc[3], pc[4]
    for r in range(q.shape[0]):
        qh[r] = q[r] + h * v[r] + cqa * a[r] + cqg * g[r]
        vh[r] = v[r] + cva * a[r] + cvg * g[r]


@kernel
def update(pc, upd, qh, vh, a1, a, g, q1, v1, g1):
    """``q_{n+1}``, ``v_{n+1}``, ``g_{n+1}`` into ``q1``, ``v1``, ``g1`` from the predictors,
    the new acceleration ``a1`` and the old ``a``, ``g`` (``g1`` may be ``g``, and ``q1``, ``v1``
    may be ``qh``, ``vh``: every entry is read before it is written)."""
    bh2, gh = pc[5], pc[6]
    ga, gan, ggn = upd[0], upd[1], upd[2]
    for r in range(qh.shape[0]):
        q1[r] = qh[r] + bh2 * a1[r]
        v1[r] = vh[r] + gh * a1[r]
        g1[r] = ga * a1[r] + gan * a[r] + ggn * g[r]
