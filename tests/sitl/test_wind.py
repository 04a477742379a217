"""Dryden turbulence: realised standard deviation and spectrum against the requested ones."""

import math

import numpy as np
import pytest

from sitl.plant.wind import TurbulenceParams, Wind, WindParams, dryden_low_altitude, dryden_psd

DT = 0.01  # the filters are exact at any step; 100 Hz keeps the test short


def realise(sigma, seconds, seeds, mean=(3.0, 0.0, 0.0), altitude=2.0):
    p = WindParams(mean, TurbulenceParams(True, altitude, 0.0, sigma))
    runs = []
    for seed in seeds:
        w = Wind(p, seed, DT)
        runs.append(np.array([w.turbulence_step() for _ in range(int(seconds / DT))]))
    return np.stack(runs), w


def test_low_altitude_scales_follow_mil_f_8785c():
    sigma, length = dryden_low_altitude(altitude_m=50 * 0.3048, w20_m_s=15.0)
    k = 0.177 + 0.000823 * 50
    assert math.isclose(length[2], 50 * 0.3048)
    assert math.isclose(length[0], 50 / k**1.2 * 0.3048)
    assert math.isclose(sigma[2], 1.5) and math.isclose(sigma[0], 1.5 / k**0.4)


def test_realised_standard_deviation_matches_the_request():
    """Each run lasts 600 s; u's correlation time L_u/V = 15.4/3 = 5.1 s gives ~120 independent
    samples per run, 8 runs ~ 1000, so the std's relative standard error is ~1/sqrt(2*1000) = 2.2%;
    5% is more than two standard errors."""
    sigma = (0.6, 0.5, 0.3)
    runs, _ = realise(sigma, 600.0, seeds=range(8))
    realised = runs.reshape(-1, 3).std(axis=0)
    np.testing.assert_allclose(realised, sigma, rtol=0.05)


@pytest.mark.parametrize("axis", [0, 1, 2])
def test_realised_spectrum_matches_dryden(axis):
    """Welch estimate (segments of 200 s, Hann window, averaged over 8 runs of 2000 s) compared
    with the analytic one-sided Dryden PSD, averaged in octave bands from 0.05 to 3 rad/s.
    ~640 averaged segments*bins per band give a relative error of a few percent; 20% allows for
    the Hann window's bias at the lowest band."""
    sigma = (0.6, 0.5, 0.3)
    runs, w = realise(sigma, 2000.0, seeds=range(8))
    x = runs[:, :, axis]
    nseg = int(200.0 / DT)
    win = np.hanning(nseg)
    scale = DT / (win**2).sum()
    psds = []
    for run in x:
        for k in range(0, len(run) - nseg + 1, nseg // 2):
            seg = run[k : k + nseg] - run[k : k + nseg].mean()
            spec = np.abs(np.fft.rfft(seg * win)) ** 2 * scale
            psds.append(spec)
    psd_hz = np.mean(psds, axis=0)
    psd_hz[1:-1] *= 2  # one-sided
    freqs_rad = 2 * np.pi * np.fft.rfftfreq(nseg, DT)
    psd_rad = psd_hz / (2 * np.pi)  # per rad/s
    expected = dryden_psd(freqs_rad, sigma[axis], w.lengths[axis], w.airspeed, "uvw"[axis])
    edges = 0.05 * 2.0 ** np.arange(0, 7)
    for lo, hi in zip(edges[:-1], edges[1:]):
        band = (freqs_rad >= lo) & (freqs_rad < hi)
        ratio = psd_rad[band].mean() / expected[band].mean()
        assert 0.8 < ratio < 1.2, (lo, hi, ratio)


def test_same_seed_same_wind_different_seed_different_wind():
    a, _ = realise((0.5, 0.5, 0.2), 5.0, seeds=[3])
    b, _ = realise((0.5, 0.5, 0.2), 5.0, seeds=[3])
    c, _ = realise((0.5, 0.5, 0.2), 5.0, seeds=[4])
    assert np.array_equal(a, b) and not np.allclose(a, c)


def test_turbulence_is_aligned_with_the_mean_wind():
    """Mean wind towards east: the longitudinal (larger) component appears on the y axis. Over
    2000 s the sample mean of a process with sigma 0.8 m/s and correlation time 5.1 s has a
    standard error of 0.8 * sqrt(2 * 5.1 / 2000) = 0.057 m/s; the bound is four of those."""
    p = WindParams((0.0, 3.0, 0.0), TurbulenceParams(True, 2.0, 0.0, (0.8, 0.1, 0.1)))
    w = Wind(p, 1, DT)
    samples = np.array([w.step() for _ in range(int(2000 / DT))])
    assert math.isclose(samples[:, 1].mean(), 3.0, abs_tol=0.23)
    assert samples[:, 1].std() > 3 * samples[:, 0].std()
