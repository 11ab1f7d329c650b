"""Uncertainty and identifiability of a whole-cycle fit: the covariance of the fitted
log-parameters, its propagation to every quantity, and the per-parameter verdict."""

from __future__ import annotations

import math

import numpy as np

REL_LIMIT = 1.0  # relative 1-sigma above which a parameter is not identifiable
SIGNATURE = 10.0  # dashpot force signature / RMS residual below which cd is not identifiable


def gn_gain(res, jac) -> float:
    """Fraction of the squared residual that one more Gauss-Newton step of the
    linearised model would remove (at a periodic fit with the window's start state
    as a free column: what releasing the periodic state could gain)."""
    step = np.linalg.lstsq(jac, -res, rcond=None)[0]
    r0 = float(res @ res)
    return 1.0 - float(np.sum((res + jac @ step) ** 2)) / r0 if r0 > 0 else 0.0


def covariance(res, jac):
    """``s^2 (J^T J)^-1`` with ``s^2 = |r|^2/(n - p)``, by SVD without truncation
    (a degenerate direction gives an infinite variance, not a truncated one)."""
    n, p = jac.shape
    s2 = float(np.sum(res**2)) / max(n - p, 1)
    norm = np.sqrt(np.sum(jac**2, axis=0))
    norm[norm == 0] = 1.0
    _, sv, vt = np.linalg.svd(jac / norm, full_matrices=False)
    with np.errstate(divide="ignore", invalid="ignore"):
        inv_sv2 = np.where(sv > 0, 1.0 / sv**2, np.inf)
        cov = (vt.T * inv_sv2) @ vt
    cov = cov / np.outer(norm, norm) * s2
    return np.where(np.isfinite(cov), cov, np.inf)


def propagate(cov, gradients: dict) -> dict:
    """Relative 1-sigma of each quantity from the covariance of the log-parameters:
    ``sqrt(g^T C g)`` with ``g = d ln q / d ln p`` (the surface model's
    :meth:`~vetica_cli.surfaces.SurfaceModel.log_gradients`; nuisance columns zero)."""
    out = {}
    for name, g in gradients.items():
        gv = np.zeros(len(cov))
        gv[: len(g)] = g
        out[name] = float(math.sqrt(max(gv @ cov @ gv, 0.0)))
    return out


def identifiability(names, rel, at_bound, params: dict, th: dict, t_contact, t_free, h, sigma_kg, rms):
    """Per fitted SLS parameter: (identifiable, reason).

    Not identifiable: relative 1-sigma (Jacobian, start state unknown) above
    ``REL_LIMIT``, or at a bound of the fit range, or when the fitted dashpot
    does not act within the record: its signature in the force within a tap,
    ``(k0/Kg) max(relaxation in a contact, creep between taps)`` relative to
    the peak force, is below ``SIGNATURE`` times the relative RMS residual
    (cd then has only a lower bound and the surface shows only its glassy
    stiffness ``Kg = k0 + k_inf``), or it relaxes within one sample (cd has
    only an upper bound).  ``params`` = fitted ``k_inf, k0, cd``; ``th`` their
    theory values (``tau_r``, ``tau_c``, ``k_g``).
    """
    relax = -math.expm1(-t_contact / th["tau_r"])  # fraction the dashpot relaxes in one contact
    creep = -math.expm1(-t_free / th["tau_c"])  # fraction it creeps between taps
    signature = params["k0"] / th["k_g"] * max(relax, creep)
    frozen = signature < SIGNATURE * rms
    why_frozen = (
        f"the dashpot hardly moves within a tap (relaxes {100 * relax:.2g} % in contact, creeps "
        f"{100 * creep:.2g} % between taps; force signature {signature:.2g} of the peak < "
        f"{SIGNATURE:g} x RMS residual {rms:.2g})"
    )
    out = {}
    for i, name in enumerate(names):
        if name == "cd":
            extra = f"; {why_frozen}: cd has only a lower bound" if frozen else ""
        elif name in ("k0", "k_inf"):
            extra = f"; {why_frozen}: only k_g = k0 + k_inf is determined (1-sigma {sigma_kg:.2g})" if frozen else ""
        else:
            extra = ""
        if at_bound[i]:
            out[name] = (False, "at the bound of the fit range" + extra)
        elif not math.isfinite(rel[i]) or rel[i] > REL_LIMIT:
            out[name] = (False, f"relative 1-sigma uncertainty {rel[i]:.3g} > {REL_LIMIT:g} (Jacobian)" + extra)
        elif extra:
            out[name] = (False, extra[2:])
        elif name == "cd" and th["tau_r"] < h and th["tau_c"] < h:
            out[name] = (False, "the dashpot relaxes within one sample: cd has only an upper bound")
        else:
            out[name] = (True, f"relative 1-sigma uncertainty {rel[i]:.2g}")
    return out
