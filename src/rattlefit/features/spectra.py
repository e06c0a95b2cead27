"""Spectra of the relative motion: FFT magnitude, band features and the gear rattle index.

Rattle is chaotic: two runs of the same rig, or of the model from slightly different initial
conditions, have different time histories but the same statistics. rattlefit therefore compares
*spectral features*: the Welch power spectral density of Δθ* (Hann window, 50 % overlap,
one-sided, rad²/Hz, as ``scipy.signal.welch``) averaged in log-spaced frequency bands, in
log10. All functions accept numpy or JAX arrays and are differentiable in JAX; on concrete
arrays they compute in numpy (nothing to compile), while traced in JAX.
"""

from __future__ import annotations

import dataclasses
import math

import numpy as np
from jaxtyping import Array, ArrayLike, Float

from ..io.recording import quantisation_std
from ..util import array_namespace

#: Frequency band of the gear rattle index, eq. (10) of the seed paper, Hz.
IGR_BAND_HZ = (20.0, 5000.0)


def default_segment_length(sample_rate: float) -> int:
    """Welch segment length: the power of two nearest 0.4 s (4096 samples at 10 kHz)."""
    return int(2 ** round(math.log2(0.4 * sample_rate)))


@dataclasses.dataclass(frozen=True)
class BandSpec:
    """Log-spaced frequency bands over the Welch frequency grid (immutable).

    Attributes
    ----------
    sample_rate : Hz.
    segment_length : Welch segment length, samples.
    f_low, f_high : outer band edges, Hz.
    n_bands : bands requested; bands that would hold no frequency bin are merged with their
        neighbour, so :attr:`edges` may have fewer.
    """

    sample_rate: float = 10_000.0
    segment_length: int = 4096
    f_low: float = 4.0
    f_high: float = 5000.0
    n_bands: int = 32

    def __post_init__(self):
        nyquist = self.sample_rate / 2
        if not (0 < self.f_low < self.f_high <= nyquist + 1e-9):
            raise ValueError(f"bands need 0 < f_low < f_high ≤ Nyquist ({nyquist} Hz)")

    @property
    def frequencies(self) -> np.ndarray:
        """Welch frequency grid, Hz."""
        return np.fft.rfftfreq(self.segment_length, 1.0 / self.sample_rate)

    @property
    def edges(self) -> np.ndarray:
        """Band edges (Hz) after merging bands that hold no bin."""
        f = self.frequencies
        raw = np.geomspace(self.f_low, self.f_high, self.n_bands + 1)
        keep = [raw[0]]
        for e in raw[1:]:
            if np.any((f >= keep[-1]) & (f < e)):
                keep.append(e)
        if len(keep) == 1:
            raise ValueError("no frequency bin falls inside the bands")
        keep[-1] = raw[-1]
        return np.asarray(keep)

    @property
    def centers(self) -> np.ndarray:
        """Geometric band centres, Hz."""
        e = self.edges
        return np.sqrt(e[:-1] * e[1:])

    @property
    def matrix(self) -> np.ndarray:
        """(n_bands, n_bins) averaging matrix: row b averages the bins in band b."""
        f, e = self.frequencies, self.edges
        inside = (f[None, :] >= e[:-1, None]) & (f[None, :] < e[1:, None])
        inside[-1] |= f == e[-1]
        return inside / inside.sum(axis=1, keepdims=True)

    @classmethod
    def for_recording(cls, sample_rate: float, **kw) -> BandSpec:
        """Bands for a recording's sample rate, up to its Nyquist frequency."""
        kw.setdefault("f_high", min(5000.0, sample_rate / 2))
        return cls(
            sample_rate=sample_rate, segment_length=default_segment_length(sample_rate), **kw
        )


def welch_psd(
    x: Float[ArrayLike, "*batch N"], sample_rate: float, segment_length: int
) -> Float[Array, "*batch F"]:
    """One-sided Welch PSD (rad²/Hz): Hann window, 50 % overlap, each segment's mean removed.

    Matches ``scipy.signal.welch(x, fs, nperseg=segment_length)`` (its defaults). Computed
    in numpy for concrete input and in JAX while traced (:func:`~rattlefit.util.array_namespace`),
    as are the other spectra here: a recording's features then compile nothing.
    """
    xp = array_namespace(x)
    x = xp.asarray(x)
    n = x.shape[-1]
    if n < segment_length:
        raise ValueError(f"signal of {n} samples is shorter than one segment ({segment_length})")
    step = segment_length // 2
    starts = np.arange(0, n - segment_length + 1, step)
    index = starts[:, None] + np.arange(segment_length)[None, :]
    seg = x[..., index]
    seg = seg - xp.mean(seg, axis=-1, keepdims=True)
    window = np.hanning(segment_length + 1)[:-1]  # periodic Hann, as scipy's 'hann'
    spec = xp.abs(xp.fft.rfft(seg * window, axis=-1)) ** 2
    scale = 1.0 / (sample_rate * np.sum(window**2))
    psd = xp.mean(spec, axis=-2) * scale
    one_sided = np.full(segment_length // 2 + 1, 2.0)
    one_sided[0] = 1.0
    if segment_length % 2 == 0:
        one_sided[-1] = 1.0
    return psd * one_sided


def band_power(x: Float[ArrayLike, "*batch N"], bands: BandSpec) -> Float[Array, "*batch B"]:
    """Mean Welch PSD in each band, rad²/Hz."""
    psd = welch_psd(x, bands.sample_rate, bands.segment_length)
    return psd @ array_namespace(psd).asarray(bands.matrix.T)


def spectral_features(
    x: Float[ArrayLike, "*batch N"], bands: BandSpec, *, noise_floor: float = 0.0
) -> Float[Array, "*batch B"]:
    """log10 of the band-mean PSD (rad²/Hz), plus a white ``noise_floor`` PSD if given.

    Adding the encoder quantisation floor (:func:`quantisation_floor`) to a simulated,
    unquantised signal gives the expected features of its measurement.
    """
    power = band_power(x, bands)
    return array_namespace(power).log10(power + noise_floor)


def quantisation_floor(counts_per_rev: int, gear_ratio: float, sample_rate: float) -> float:
    """One-sided PSD of the white quantisation noise of Δθ*, rad²/Hz: 2 σ² / fs."""
    return 2.0 * quantisation_std(counts_per_rev, gear_ratio) ** 2 / sample_rate


def amplitude_spectrum(
    x: Float[ArrayLike, "*batch N"], sample_rate: float
) -> tuple[np.ndarray, Array]:
    """Single-sided FFT amplitude spectrum of the mean-removed signal: (Hz, rad).

    A sinusoid of amplitude A at a bin frequency shows as A.
    """
    xp = array_namespace(x)
    x = xp.asarray(x)
    n = x.shape[-1]
    spec = xp.abs(xp.fft.rfft(x - xp.mean(x, axis=-1, keepdims=True), axis=-1)) * (2.0 / n)
    return np.fft.rfftfreq(n, 1.0 / sample_rate), spec


def rattle_index(
    x: Float[ArrayLike, "*batch N"],
    sample_rate: float,
    *,
    band: tuple[float, float] = IGR_BAND_HZ,
    segment: float = 1.0,
) -> Array:
    """Gear rattle index IGR of eq. (10), rad·Hz.

    IGR = ∫ |Δθ*(f)| df over ``band`` (default 20–5000 Hz), with |Δθ*(f)| the single-sided
    amplitude spectrum (rad) of the mean-removed Δθ* and the integral taken as the sum over
    bins times the bin width. The paper leaves the FFT length open; an integral of an FFT
    magnitude grows with record length for broadband signals, so rattlefit computes it on
    consecutive non-overlapping ``segment``-second blocks (1 Hz bins) and averages them. Only
    recordings with the same sample rate compare (the band is clipped at Nyquist).
    """
    xp = array_namespace(x)
    x = xp.asarray(x)
    n_seg = round(segment * sample_rate)
    n_blocks = x.shape[-1] // n_seg
    if n_blocks < 1:
        raise ValueError(f"signal shorter than one {segment} s IGR block")
    blocks = x[..., : n_blocks * n_seg].reshape(*x.shape[:-1], n_blocks, n_seg)
    f, amp = amplitude_spectrum(blocks, sample_rate)
    sel = (f >= band[0]) & (f <= band[1])
    df = sample_rate / n_seg
    return xp.mean(xp.sum(amp[..., sel], axis=-1) * df, axis=-1)
