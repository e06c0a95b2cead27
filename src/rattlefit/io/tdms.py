"""LabView TDMS channels in (through npTDMS): values, sample rate and unit."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..errors import RecordingError


@dataclass(frozen=True)
class TdmsChannels:
    """The channels read: ``data`` (one array each), the sample rate their ``wf_increment``
    gives (None without one) and the ``unit_string`` they share ("" without one)."""

    data: list[np.ndarray]
    sample_rate_hz: float | None
    unit: str


def tdms_channels(path: str, names: list[str]) -> TdmsChannels:
    """The channels ``names`` ("group/channel") of the TDMS file ``path``. Raises
    :class:`~rattlefit.errors.RecordingError` naming the file and the channel for an
    unreadable file, a missing channel, or channels whose rates or units differ."""
    from nptdms import TdmsFile

    try:
        tdms = TdmsFile.read(path)
    except (OSError, ValueError, KeyError) as exc:
        raise RecordingError(path, "/", f"cannot read the TDMS file ({exc})") from None
    data, rates, units = [], {}, {}
    for name in names:
        group, _, channel = name.partition("/")
        try:
            ch = tdms[group][channel]
        except KeyError:
            available = [f"{g.name}/{c.name}" for g in tdms.groups() for c in g.channels()]
            raise RecordingError(
                path, name, f"no such group/channel in the TDMS file (it has {available[:8]})"
            ) from None
        data.append(np.asarray(ch[:]))
        if "wf_increment" in ch.properties:
            rates[name] = 1.0 / float(ch.properties["wf_increment"])
        units[name] = str(ch.properties.get("unit_string", "")).strip()
    if len(set(rates.values())) > 1:
        raise RecordingError(path, names[1], f"sample rates differ between channels: {rates}")
    if len(set(units.values())) > 1:
        raise RecordingError(path, names[1], f"units differ between channels: {units}")
    rate = next(iter(rates.values())) if rates else None
    return TdmsChannels(data, rate, units[names[0]])
