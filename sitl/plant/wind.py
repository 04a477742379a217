"""Wind: a mean vector plus Dryden turbulence in the MIL-F-8785C low-altitude form.

Low altitude (h < 1000 ft, h in feet inside the formulas)::

    L_w = h,  L_u = L_v = h / (0.177 + 0.000823 h)^1.2
    sigma_w = 0.1 W20,  sigma_u = sigma_v = sigma_w / (0.177 + 0.000823 h)^0.4

with W20 the wind speed at 20 ft. The one-sided spectra in temporal frequency ``w`` [rad/s], for
the turbulence field carried past the vehicle at speed V (frozen-field hypothesis; for a
hovering vehicle V is the mean wind speed) are::

    Phi_u(w) = sigma_u^2 (2 L_u / (pi V)) / (1 + (L_u w / V)^2)
    Phi_v(w) = sigma_v^2 (L_v / (pi V)) (1 + 3 (L_v w / V)^2) / (1 + (L_v w / V)^2)^2

u is along the mean wind, v across it (horizontal), w vertical. The forming filters are
discretised exactly (u: first order; v, w: a double pole plus a zero) and their output gain is
set from the discrete stationary variance, so the realised standard deviation is the requested
one at any step length. Intensities may also be given directly (``sigma_m_s``), e.g. for the
paper's indoor fan, where W20 has no meaning.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Sequence

import numpy as np

from companion.control.jit import depends_on, jitable
from companion.control.vector import ZERO3, Real, Vec3

from .noise import GaussianStream

__all__ = [
    "TurbulenceParams",
    "WindParams",
    "dryden_low_altitude",
    "dryden_psd",
    "Wind",
    "dryden_advance",
    "dryden_gust",
    "wind_ned",
]

depends_on(__file__)  # the compiled kernel (kernel.py) calls the three laws below

FT = 0.3048


@dataclass(frozen=True)
class TurbulenceParams:
    """Dryden turbulence. ``sigma_m_s`` (u, v, w) overrides the intensities from ``w20_m_s``."""

    enabled: bool = False
    altitude_m: float = 2.0
    w20_m_s: float = 0.0
    sigma_m_s: Vec3 = (0.0, 0.0, 0.0)
    min_airspeed_m_s: float = 1.0
    """speed that carries the field past a vehicle in calm mean wind"""


@dataclass(frozen=True)
class WindParams:
    mean_ned_m_s: Vec3 = ZERO3
    turbulence: TurbulenceParams = TurbulenceParams()


def dryden_low_altitude(altitude_m: float, w20_m_s: float) -> tuple[Vec3, Vec3]:
    """``(sigma (u, v, w) [m/s], L (u, v, w) [m])`` of MIL-F-8785C below 1000 ft."""
    h = max(altitude_m / FT, 1e-3)
    k = 0.177 + 0.000823 * h
    lu = h / k**1.2 * FT
    lw = h * FT
    sw = 0.1 * w20_m_s
    su = sw / k**0.4
    return (su, su, sw), (lu, lu, lw)


def dryden_psd(omega_rad_s: np.ndarray, sigma: float, length_m: float, airspeed_m_s: float, axis: str) -> np.ndarray:
    """One-sided Dryden spectrum [(m/s)^2 / (rad/s)] at temporal frequencies ``omega_rad_s``."""
    x = length_m * omega_rad_s / airspeed_m_s
    if axis == "u":
        return sigma**2 * (2.0 * length_m / (math.pi * airspeed_m_s)) / (1.0 + x**2)
    return sigma**2 * (length_m / (math.pi * airspeed_m_s)) * (1.0 + 3.0 * x**2) / (1.0 + x**2) ** 2


def _first_order(dt: float, tc: float) -> tuple[float, float]:
    a = math.exp(-dt / tc)
    return a, math.sqrt(1.0 - a * a)


_Coeffs = tuple[float, float, float, float, float]


def _second_order(dt: float, tc: float) -> tuple[_Coeffs, tuple[float, float], np.ndarray]:
    """Exact discretisation of ``x1' = (n - x1)/T``, ``x2' = (x1 - x2)/T``, output
    ``y = sqrt(3) x1 + (1 - sqrt(3)) x2``, i.e. ``(1 + sqrt(3) T s) / (1 + T s)^2`` n.

    Returns ``(phi11, phi21, phi22, gam1, gam2)``, the output row scaled to unit stationary
    variance for unit-variance white input, and the Cholesky factor of the stationary state
    covariance (to start the filter in its stationary distribution).
    """
    a = math.exp(-dt / tc)
    h = dt / tc
    phi = a * np.array([[1.0, 0.0], [h, 1.0]])
    gam = np.array([1.0 - a, 1.0 - (1.0 + h) * a])
    c = np.array([math.sqrt(3.0), 1.0 - math.sqrt(3.0)])
    # stationary covariance: P = phi P phi^T + gam gam^T
    lhs = np.eye(4) - np.kron(phi, phi)
    p = np.linalg.solve(lhs, np.outer(gam, gam).ravel()).reshape(2, 2)
    k = 1.0 / math.sqrt(float(c @ p @ c))
    coeffs = (float(phi[0, 0]), float(phi[1, 0]), float(phi[1, 1]), float(gam[0]), float(gam[1]))
    return coeffs, (float(c[0] * k), float(c[1] * k)), np.linalg.cholesky(p)


_Filter2 = tuple[Real, Real]


@jitable
def dryden_advance(u: tuple[float, float], v: _Coeffs, w: _Coeffs, xu: Real, xv: _Filter2, xw: _Filter2,
                   n_u: Real, n_v: Real, n_w: Real) -> tuple[Real, _Filter2, _Filter2]:
    """One step of the three forming filters (coefficients of :func:`_first_order` and
    :func:`_second_order`) driven by unit white noise ``n_*``."""
    a, b = u
    xu = a * xu + b * n_u
    p11, p21, p22, g1, g2 = v
    x1, x2 = xv
    xv = (p11 * x1 + g1 * n_v, p21 * x1 + p22 * x2 + g2 * n_v)
    p11, p21, p22, g1, g2 = w
    x1, x2 = xw
    xw = (p11 * x1 + g1 * n_w, p21 * x1 + p22 * x2 + g2 * n_w)
    return xu, xv, xw


@jitable
def dryden_gust(sigma: Vec3, cv: tuple[float, float], cw: tuple[float, float], xu: Real, xv: _Filter2,
                xw: _Filter2) -> Vec3:
    """Gust (u, v, w) [m/s] in the wind axes from the filters' states."""
    return (sigma[0] * xu, sigma[1] * (cv[0] * xv[0] + cv[1] * xv[1]), sigma[2] * (cw[0] * xw[0] + cw[1] * xw[1]))


@jitable
def wind_ned(mean_ned_m_s: Vec3, cos_heading: float, sin_heading: float, gust: Vec3) -> Vec3:
    """The NED wind [m/s]: the mean plus the gust turned from the wind axes (u along the mean)."""
    m, c, s = mean_ned_m_s, cos_heading, sin_heading
    return (m[0] + c * gust[0] - s * gust[1], m[1] + s * gust[0] + c * gust[1], m[2] + gust[2])


class Wind:
    """Mean wind plus turbulence, stepped with the plant; :meth:`step` returns the NED wind."""

    def __init__(self, params: WindParams, seeds: int | Sequence[int], dt_s: float) -> None:
        self.params = params
        self.mean = params.mean_ned_m_s
        tp = params.turbulence
        self.enabled = tp.enabled
        if not self.enabled:
            return
        self._noise = GaussianStream(seeds, "wind", 3)
        m = params.mean_ned_m_s
        horiz = math.hypot(float(np.mean(m[0])), float(np.mean(m[1])))
        self.airspeed = max(math.sqrt(horiz**2 + float(np.mean(m[2])) ** 2), tp.min_airspeed_m_s)
        heading = math.atan2(float(np.mean(m[1])), float(np.mean(m[0]))) if horiz > 1e-9 else 0.0
        self._cos, self._sin = math.cos(heading), math.sin(heading)
        if any(s > 0.0 for s in tp.sigma_m_s):
            sigma = tp.sigma_m_s
            _, lengths = dryden_low_altitude(tp.altitude_m, 1.0)
        else:
            sigma, lengths = dryden_low_altitude(tp.altitude_m, tp.w20_m_s)
        self.sigma = sigma
        self.lengths = lengths
        self._u = _first_order(dt_s, lengths[0] / self.airspeed)
        self._v, self._cv, chol_v = _second_order(dt_s, lengths[1] / self.airspeed)
        self._w, self._cw, chol_w = _second_order(dt_s, lengths[2] / self.airspeed)
        # start every filter in its stationary distribution, not in calm air
        n0 = self._noise.initial()
        n1 = self._noise.initial()
        self._xu: Real = n0[0]
        self._xv = (chol_v[0, 0] * n0[1], chol_v[1, 0] * n0[1] + chol_v[1, 1] * n1[1])
        self._xw = (chol_w[0, 0] * n0[2], chol_w[1, 0] * n0[2] + chol_w[1, 1] * n1[2])
        if not self._noise.batch:
            self._xv = (float(self._xv[0]), float(self._xv[1]))
            self._xw = (float(self._xw[0]), float(self._xw[1]))

    def _advance(self) -> Vec3:
        n = self._noise.next()
        self._xu, self._xv, self._xw = dryden_advance(self._u, self._v, self._w, self._xu, self._xv, self._xw,
                                                      n[0], n[1], n[2])
        return dryden_gust(self.sigma, self._cv, self._cw, self._xu, self._xv, self._xw)

    def turbulence_step(self) -> Vec3:
        """Gust (u, v, w) [m/s] in the wind axes; zero when turbulence is off."""
        if not self.enabled:
            return ZERO3
        return self._advance()

    def step(self) -> Vec3:
        if not self.enabled:
            return self.mean
        return wind_ned(self.mean, self._cos, self._sin, self._advance())
