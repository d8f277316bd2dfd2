"""The adjoint of the bodies' residual with respect to their design data.

With the damping ``beta_d`` and the gravity held, a body's share of the residual
(:mod:`morphlab.kernels.ffrf`) is linear in its invariants and element matrices together (the
linear design fields of :data:`~morphlab.kernels.ffrf.BODIES`, :data:`~morphlab.kernels.ffrf.
FLEX` and :data:`~morphlab.kernels.ffrf.ELEMENTS`). So for a state ``x`` and a vector ``μ``
there is one array ``G`` in the layout of those data with ``μ^T R(x; Z) = <G, Z>`` for every
``Z``: :func:`data_gradient` forms it, one pass over the bodies and elements whatever the
number of design variables. The adjoint's design share of a variable that changes these data
alone is then ``<G, dD/dp>``, summed over the steps (``docs/theory.md`` §7.5), instead of one
evaluation of the residual per variable and step.

The stiffness is the exception. ``K_e`` annihilates the element's rigid motions, which make
most of its coordinates ``q_j`` in a frame of many elements, so ``dK . sum_n μ_i q_j`` would
be a sum of terms up to 1e4-1e5 times the result (measured on a 32-element single-frame
pendulum): the gradient would lose four or five digits to round-off. Its share is taken per
variable and step instead, over the stiffness entries the variable changes alone
(:func:`stiffness_share`: ``w_f μ_e^T dK_e d_e``, ``dK_e d_e`` formed first, as the residual
forms ``K d``), which costs the variable's elements, not its frame.

With ``f = w_m a_R - w_f g`` and the body's ``μ_R`` (2), ``μ_θ`` and ``μ_k`` of its flexible
coordinates (``Ĩ = [[0, -1], [1, 0]]``, ``A = Rot(theta)``), the terms of ``G`` are::

    m        μ_R . f
    I_u      A^T (Ĩ^T (w_m θ'' μ_R + μ_θ f) - w_f θ'^2 μ_R)        (=: g_c)
    I_00     w_m μ_θ θ''
    I_S,k    g_c q_k + w_m A^T μ_R a_k + 2 w_f θ' A^T Ĩ^T μ_R q'_k + μ_k A^T f
    I_0S,k   2 w_m μ_θ θ'' q_k + 2 w_f θ' μ_θ q'_k - w_f θ'^2 μ_k
    I_0ĨS,k  w_m (μ_θ a_k + θ'' μ_k)
    M_ij     (w_m μ_θ θ'' q_i + 2 w_f θ' μ_θ q'_i - w_f θ'^2 μ_i) q_j + w_m μ_i a_j
    S̃_ij     w_m (μ_θ a_i + θ'' μ_i) q_j + 2 w_f θ' μ_i q'_j
    K_ij     w_f μ_i (q_j + beta_d q'_j)   (per variable: :func:`stiffness_share`)

(``k``: a flexible coordinate; ``i, j``: an element's DOFs, zero where the reference condition
removes one). The stress maps do not enter the residual: their share is zero.
"""

import numpy as np

from ._jit import inner

#: The fields of the data gradient, in the order of its offsets (:func:`data_gradient`).
FIELDS = (("bodies", "scal"), ("flex", "IS"), ("flex", "I0S"), ("flex", "I0IS"),
          ("elements", "M"), ("elements", "St"))
#: The field of :func:`stiffness_share`.
STIFFNESS = ("elements", "K")


@inner
def data_gradient(B, Fx, E, g, x, w, mu, G, GO, L):
    """Add ``d(μ[:, c]^T R)/dD`` to ``G[:, c]`` for every column ``c`` of ``mu`` (n, m): ``R``
    the bodies' residual share of the state ``x`` with weights ``w``, ``D`` their linear
    design data but the stiffness (module docstring; its rows of ``G`` are not written).
    ``B, Fx, E``: the tables of the bodies' kinds (their design values are not read: only the
    topology), ``g`` (2,) the gravity; ``G``
    (n_design, m): in the layout of the flat design data, the field ``FIELDS[f]`` from row
    ``GO[f]`` (item after item, each row-major; no rows: nothing to form); ``L`` (>= 4, 6)
    scratch."""
    if B is None:  # the model has none of this kind
        return
    if G.shape[0] == 0:  # no variable of this kind
        return
    wm, wf = w.wm, w.wf
    m = mu.shape[1]
    q, v, a = x.q, x.v, x.a
    o_sc, o_is, o_s, o_is2, o_m, o_st = GO[0], GO[1], GO[2], GO[3], GO[4], GO[5]
    for b in range(B.ref.shape[0]):
        iR0, iR1, ith = B.ref[b, 0], B.ref[b, 1], B.ref[b, 2]
        c, s = np.cos(q[ith]), np.sin(q[ith])
        thd, tha = v[ith], a[ith]
        fx = wm * a[iR0] - wf * g[0]
        fy = wm * a[iR1] - wf * g[1]
        ATfx, ATfy = c * fx + s * fy, -s * fx + c * fy
        row = o_sc + 4 * b
        for r in range(m):
            mx, my, mt = mu[iR0, r], mu[iR1, r], mu[ith, r]
            px = wm * tha * mx + mt * fx
            py = wm * tha * my + mt * fy
            hx = py - wf * thd * thd * mx  # Ĩ^T p - w_f θ'^2 μ_R
            hy = -px - wf * thd * thd * my
            gcx, gcy = c * hx + s * hy, -s * hx + c * hy
            G[row, r] += mx * fx + my * fy
            G[row + 1, r] += gcx
            G[row + 2, r] += gcy
            G[row + 3, r] += wm * mt * tha
            ATmx, ATmy = c * mx + s * my, -s * mx + c * my  # A^T μ_R
            AIx, AIy = c * my - s * mx, -s * my - c * mx  # A^T Ĩ^T μ_R
            for k in range(B.flex[b, 0], B.flex[b, 1]):
                d = Fx.dof[k]
                qk, vk, ak, mk = q[d], v[d], a[d], mu[d, r]
                G[o_is + 2 * k, r] += (gcx * qk + wm * ATmx * ak + 2.0 * wf * thd * AIx * vk
                                       + mk * ATfx)
                G[o_is + 2 * k + 1, r] += (gcy * qk + wm * ATmy * ak + 2.0 * wf * thd * AIy * vk
                                           + mk * ATfy)
                G[o_s + k, r] += (2.0 * (wm * mt * tha * qk + wf * thd * mt * vk)
                                  - wf * thd * thd * mk)
                G[o_is2 + k, r] += wm * (mt * ak + tha * mk)
    for e in range(E.fdof.shape[0]):
        b = E.body[e]
        ith = B.ref[b, 2]
        thd, tha = v[ith], a[ith]
        for i in range(6):
            f = E.fdof[e, i]
            if f >= 0:
                d = Fx.dof[f]
                L[0, i], L[1, i], L[2, i] = q[d], v[d], a[d]
            else:
                L[0, i], L[1, i], L[2, i] = 0.0, 0.0, 0.0
        for r in range(m):
            mt = mu[ith, r]
            for i in range(6):
                f = E.fdof[e, i]
                L[3, i] = mu[Fx.dof[f], r] if f >= 0 else 0.0
            for i in range(6):
                mi = L[3, i]
                al = wm * mt * tha * L[0, i] + 2.0 * wf * thd * mt * L[1, i] - wf * thd * thd * mi
                am = wm * mi
                sq = wm * (mt * L[2, i] + tha * mi)
                sv = 2.0 * wf * thd * mi
                row = 36 * e + 6 * i
                for j in range(6):
                    G[o_m + row + j, r] += al * L[0, j] + am * L[2, j]
                    G[o_st + row + j, r] += sq * L[0, j] + sv * L[1, j]
    for i in range(6):
        for j in range(4):
            L[j, i] = 0.0


@inner
def stiffness_share(B, Fx, E, x, w, mu, KO, KX, KE, KV, grad, L):
    """``grad[KX[u], c] -= w_f μ_e^T dK_e (q_e + beta_d q'_e)`` summed over the elements
    ``e = KE[k]``, ``KO[u] <= k < KO[u + 1]``, for every unit ``u`` and column ``c`` of
    ``mu`` (module docstring): ``KV[k]`` (36,) the variable's derivatives of element ``e``'s
    stiffness (row-major; zero where it does not change it). ``L`` (>= 4, 6) scratch."""
    if B is None:  # the model has none of this kind
        return
    wf = w.wf
    for u in range(KX.shape[0]):
        for k in range(KO[u], KO[u + 1]):
            e = KE[k]
            beta = B.damp[E.body[e]]
            for j in range(6):
                f = E.fdof[e, j]
                L[0, j] = x.q[Fx.dof[f]] + beta * x.v[Fx.dof[f]] if f >= 0 else 0.0
            for r in range(mu.shape[1]):
                acc = 0.0 * mu[0, r]
                for i in range(6):
                    f = E.fdof[e, i]
                    if f >= 0:
                        row = 0.0 * acc
                        for j in range(6):
                            row += KV[k, 6 * i + j] * L[0, j]
                        acc += mu[Fx.dof[f], r] * row
                grad[KX[u], r] -= wf * acc
    for j in range(6):
        L[0, j] = 0.0
