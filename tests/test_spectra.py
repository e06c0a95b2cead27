import numpy as np
import pytest
from scipy.signal import welch

from rattlefit.features.spectra import (
    BandSpec,
    amplitude_spectrum,
    band_power,
    quantisation_floor,
    rattle_index,
    spectral_features,
    welch_psd,
)

RANDOM_WALK_SEED = 0  # the signal compared with scipy's Welch
TRACED_SEED = 3  # the signal computed traced and concrete
WHITE_SEED = 1  # white noise
ENCODER_SEED = 2  # the irregular shaft motions that are quantised
WHITE_TOLERANCE = 0.1  # relative: a band's Welch estimate of 200 000 samples scatters ~ a few %
FLOOR_TOLERANCE = 0.15  # relative: the quantisation error is white only approximately


def test_welch_matches_scipy():
    rng = np.random.default_rng(RANDOM_WALK_SEED)
    x = np.cumsum(rng.normal(size=30000)) * 1e-5 + 1e-3 * np.sin(
        2 * np.pi * 16 * np.arange(30000) / 1e4
    )
    f, p = welch(x, fs=1e4, nperseg=4096)
    ours = np.asarray(welch_psd(x, 1e4, 4096))
    np.testing.assert_allclose(ours, p, rtol=1e-10, atol=1e-30)
    assert np.allclose(BandSpec().frequencies, f)


def test_spectra_are_computed_alike_traced_and_concrete():
    # a recording's features are computed in numpy, a simulation's inside the compiled fit in
    # JAX: both must be scipy's Welch PSD (checked above on the numpy side) to rounding
    import jax

    rng = np.random.default_rng(TRACED_SEED)
    x = np.cumsum(rng.normal(size=(2, 30000)), axis=1) * 1e-5
    bands = BandSpec()
    concrete = spectral_features(x, bands, noise_floor=1e-14)
    assert isinstance(concrete, np.ndarray)  # nothing compiled for a recording
    traced = jax.jit(lambda y: spectral_features(y, bands, noise_floor=1e-14))(x)
    np.testing.assert_allclose(np.asarray(traced), concrete, rtol=0, atol=1e-12)
    igr = jax.jit(lambda y: rattle_index(y, 1e4))(x)
    np.testing.assert_allclose(np.asarray(igr), rattle_index(x, 1e4), rtol=1e-12)


def test_white_noise_band_power_is_its_level():
    # white noise of variance σ² has one-sided PSD 2σ²/fs in every band
    rng = np.random.default_rng(WHITE_SEED)
    sigma = 3e-5
    x = rng.normal(scale=sigma, size=200_000)
    bp = np.asarray(band_power(x, BandSpec(n_bands=8, f_low=100)))
    np.testing.assert_allclose(bp, 2 * sigma**2 / 1e4, rtol=WHITE_TOLERANCE)


def test_quantisation_floor_of_real_encoders():
    # Quantising two irregular shaft motions the way the rig does gives the floor of eq. (8).
    rng = np.random.default_rng(ENCODER_SEED)
    t = np.arange(100_000) / 1e4
    quantum = 2 * np.pi / 40000
    th1 = 52.36 * t + rng.uniform(0, 7 * quantum, size=t.size)
    th2 = th1 * 19 / 41 + rng.uniform(0, 7 * quantum, size=t.size)
    c1 = np.floor(th1 * 40000 / (2 * np.pi))
    c2 = np.floor(th2 * 40000 / (2 * np.pi))
    d = 2 * np.pi / 40000 * (c1 - c2 * 41 / 19)
    exact = th1 - th2 * 41 / 19
    bp = np.asarray(band_power(d - exact, BandSpec(n_bands=6, f_low=200)))
    floor = quantisation_floor(40000, 41 / 19, 1e4)
    np.testing.assert_allclose(bp, floor, rtol=FLOOR_TOLERANCE)


def test_amplitude_spectrum_of_sinusoid():
    t = np.arange(10000) / 1e4
    f, a = amplitude_spectrum(2e-3 * np.sin(2 * np.pi * 50 * t), 1e4)
    assert f[np.argmax(a)] == 50
    assert float(np.max(a)) == pytest.approx(2e-3, rel=1e-9)


def test_rattle_index_of_sinusoids():
    # IGR of a sum of bin-centred sinusoids inside 20–5000 Hz is the sum of their amplitudes
    # times the 1 Hz bin; a component outside the band does not count.
    t = np.arange(30000) / 1e4
    x = (
        1e-3 * np.sin(2 * np.pi * 100 * t)
        + 5e-4 * np.cos(2 * np.pi * 1234 * t)
        + 1e-2 * np.sin(2 * np.pi * 8 * t)
    )
    assert float(rattle_index(x, 1e4)) == pytest.approx(1.5e-3, rel=1e-6)


def test_bands_never_empty():
    b = BandSpec(f_low=1.0, n_bands=64)
    assert np.all(b.matrix.sum(axis=1) > 0.999)
    assert len(b.centers) < 64
