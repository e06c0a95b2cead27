"""Drive-cycle-folded statistics against closed forms."""

from __future__ import annotations

import math

import jax
import jax.numpy as jnp
import numpy as np
import pytest

from rattlefit.features.folded import (
    PHASE_BINS,
    drive_phase,
    folded_statistics,
    speed_maximum_phase,
)
from rattlefit.features.orders import CONTACT_BAND

FS, F, N = 10_000.0, 7.3, 100_000  # 73 whole cycles, each sample at another phase


def overlap(a, b, lo, hi):
    return max(0.0, min(b, hi) - max(a, lo))


def sine_statistics(bins):
    """Per bin of the cycle: mean of sin(2πφ), and the shares above and below ±(1 − 2·band)."""
    edge = math.asin(1.0 - 2.0 * CONTACT_BAND) / (2 * math.pi)
    out = np.zeros((3, bins))
    for k in range(bins):
        a, b = k / bins, (k + 1) / bins
        out[0, k] = (math.cos(2 * math.pi * a) - math.cos(2 * math.pi * b)) / (2 * math.pi) * bins
        out[1, k] = overlap(a, b, edge, 0.5 - edge) * bins
        out[2, k] = overlap(a, b, 0.5 + edge, 1.0 - edge) * bins
    return out.reshape(-1)


def test_a_drive_synchronous_sine_folds_to_its_closed_form():
    phase = drive_phase(N, FS, F)
    x = 3e-3 * np.sin(2 * np.pi * phase) + 0.4  # any scale and offset: the flanks are ±1
    got = folded_statistics(x, phase)
    assert got.shape == (3 * PHASE_BINS,)
    np.testing.assert_allclose(got, sine_statistics(PHASE_BINS), atol=4e-3)


def test_the_phase_origin_rotates_the_bins_and_jax_agrees_with_numpy():
    shift = 3 / PHASE_BINS
    x = np.sin(2 * np.pi * drive_phase(N, FS, F))
    rotated = folded_statistics(x, drive_phase(N, FS, F, shift))
    plain = folded_statistics(x, drive_phase(N, FS, F)).reshape(3, -1)
    np.testing.assert_allclose(rotated.reshape(3, -1), np.roll(plain, -3, axis=1), atol=4e-3)
    batch = np.stack([x, -x])
    phase = jnp.asarray(drive_phase(N, FS, F))
    traced = np.asarray(jax.jit(lambda v: folded_statistics(v, phase))(jnp.asarray(batch)))
    np.testing.assert_allclose(traced[0], plain.reshape(-1), atol=1e-9)
    # −x: positions flip sign, flanks swap
    flipped = plain * np.array([[-1.0], [1.0], [1.0]])
    np.testing.assert_allclose(traced[1].reshape(3, -1), flipped[[0, 2, 1]], atol=1e-9)


@pytest.mark.parametrize("peak", [0.0, 0.2, 0.55, 0.9])
def test_speed_maximum_phase_finds_the_fastest_point(peak):
    # angle c cos ωt + s sin ωt whose derivative peaks at phase `peak`
    c, s = -math.sin(2 * math.pi * peak), math.cos(2 * math.pi * peak)
    assert speed_maximum_phase(c, s) == pytest.approx(peak, abs=1e-12)
    phi = np.linspace(0, 1, 100_001)
    speed = -c * np.sin(2 * np.pi * phi) + s * np.cos(2 * np.pi * phi)
    assert phi[np.argmax(speed)] == pytest.approx(peak, abs=1e-4)
