"""A recording turned into the model's inputs: geometry, drive, measured features, priors.

:func:`setup` is the one place where the recording's metadata meets the model, so that
``info``, ``identify`` and later ``diagnose`` see the same gear pair, the same drive and the
same spectral features.
"""

from __future__ import annotations

import dataclasses

import numpy as np

from .features.folded import cycle_phase, folded_statistics
from .features.spectra import BandSpec, quantisation_floor, rattle_index, spectral_features
from .io.recording import Recording
from .physics.drive import Drive
from .physics.geometry import GearGeometry
from .physics.model import RattleModel
from .physics.oil import dynamic_viscosity

#: Harmonics of the fluctuation frequency in the fitted drive.
DRIVE_HARMONICS = 6


@dataclasses.dataclass(frozen=True)
class RigSetup:
    """Everything needed to simulate and compare one recording (immutable).

    Attributes
    ----------
    recording : the validated recording.
    geometry : the gear pair's geometry.
    model : the smoothed one-dof model of that pair.
    drive : θ1(t): a smooth fit to the primary encoder (``drive="measured"``) or the
        commanded law (``drive="commanded"``).
    bands : spectral bands for the recording's sample rate.
    noise_floor : quantisation PSD of Δθ*, rad²/Hz (eq. 8).
    features : measured log10 band PSDs.
    viscosity : dynamic viscosity of the oil at the recorded temperature (ASTM D341), Pa s.
    """

    recording: Recording
    geometry: GearGeometry
    model: RattleModel
    drive: Drive
    bands: BandSpec
    noise_floor: float
    features: np.ndarray
    viscosity: float

    @property
    def duration(self) -> float:
        return self.recording.duration

    @property
    def sample_rate(self) -> float:
        return self.recording.sample_rate_hz

    def no_rattle_drag_torque(self) -> float:
        """Drag torque above which the pair does not rattle, I2·(r1/r2)·max|θ̈1|, N m."""
        g = self.geometry
        ratio = g.pitch_radius_driving / g.pitch_radius_driven
        return g.driven_inertia * ratio * self.drive.max_acceleration()

    def folded(self, n: int | None = None) -> np.ndarray:
        """The drive-cycle-folded statistics of the measured Δθ* (its first ``n`` samples,
        default all), phase zero at the fitted drive's speed maximum
        (:mod:`rattlefit.features.folded`): (3 · bins,)."""
        x = self.recording.relative_motion[:n]
        return np.asarray(folded_statistics(x, cycle_phase(self.drive, x.size, self.sample_rate)))

    def rattle_index(self) -> float:
        """IGR of the measured Δθ* (rad·Hz), eq. (10)."""
        return float(rattle_index(self.recording.relative_motion, self.sample_rate))


def setup(
    recording: Recording, *, drive: str = "measured", model_options: dict | None = None
) -> RigSetup:
    """Build the :class:`RigSetup` of ``recording``.

    ``drive="measured"`` (default) fits a constant speed plus the first
    :data:`DRIVE_HARMONICS` harmonics of the fluctuation frequency to the primary encoder,
    because a real motor never follows its command exactly; ``"commanded"`` uses eq. (9).
    """
    geometry = GearGeometry.from_spec(recording.gear_pair)
    op = recording.operating
    if drive == "measured":
        drv = Drive.fit(
            recording.time,
            recording.theta_primary,
            op.drive_frequency_hz,
            n_harmonics=DRIVE_HARMONICS,
        )
    elif drive == "commanded":
        drv = Drive.commanded(
            op.drive_mean_speed_rad_s, op.drive_speed_amplitude_rad_s, op.drive_frequency_hz
        )
    else:
        raise ValueError(f"drive must be 'measured' or 'commanded', got {drive!r}")
    bands = BandSpec.for_recording(recording.sample_rate_hz)
    floor = quantisation_floor(
        recording.counts_per_rev, geometry.gear_ratio, recording.sample_rate_hz
    )
    features = np.asarray(spectral_features(recording.relative_motion, bands))
    oil = recording.oil
    mu = dynamic_viscosity(
        op.oil_temperature_c, oil.viscosity_40c_cst, oil.viscosity_100c_cst, oil.density_kg_m3
    )
    model = RattleModel.from_geometry(geometry, **(model_options or {}))
    return RigSetup(recording, geometry, model, drv, bands, floor, features, mu)
