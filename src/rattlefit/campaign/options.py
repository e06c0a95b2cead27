"""Options of a campaign: what is computed for every identification (:class:`CampaignOptions`)
and where it runs (:class:`ClusterOptions`). Both are frozen and checked at construction."""

from __future__ import annotations

import dataclasses
import os

from ..errors import RattlefitError
from ..physics.effects import EFFECTS
from ..problem.options import FitOptions


def _check(ok: bool, message: str) -> None:
    if not ok:
        raise RattlefitError(message)


@dataclasses.dataclass(frozen=True)
class CampaignOptions:
    """What a campaign computes for each identification (each manifest unit).

    fit : the options of every identification (:class:`~rattlefit.FitOptions`; its seed
        seeds every fit, its ``likelihood`` chooses the synthetic or the learned
        likelihood). Default ``FitOptions()``.
    diagnose : also diagnose each unit (:func:`rattlefit.diagnose`, starting from its
        identification and judged on its likelihood). Default False.
    effects : the effects diagnose tries (names of
        :data:`rattlefit.physics.effects.EFFECTS`); None: the default ones
        (:data:`~rattlefit.physics.effects.DEFAULT_EFFECTS`). Default None.
    sample_steps : steps of each unit's posterior chain (:func:`rattlefit.sample`, started
        from its identification); 0: no sampling. Default 0.
    sample_walkers : emcee walkers of each chain. Default 16.
    resimulations : realisations simulated at each recording's fitted parameters for the
        report's model IGR (≥ 1). Default 4.

    Raises :class:`~rattlefit.errors.RattlefitError` naming the option for a value out of
    range or an unknown effect.
    """

    fit: FitOptions = dataclasses.field(default_factory=FitOptions)
    diagnose: bool = False
    effects: tuple[str, ...] | None = None
    sample_steps: int = 0
    sample_walkers: int = 16
    resimulations: int = 4

    def __post_init__(self):
        _check(isinstance(self.fit, FitOptions), "CampaignOptions.fit must be a FitOptions")
        if self.effects is not None:
            object.__setattr__(self, "effects", tuple(self.effects))
            unknown = [e for e in self.effects if e not in EFFECTS]
            _check(
                bool(self.effects) and not unknown,
                f"CampaignOptions.effects: unknown effect(s) {', '.join(unknown) or '(none)'}; "
                f"known: {', '.join(EFFECTS)}",
            )
        _check(
            self.sample_steps == 0 or self.sample_steps >= 2,
            f"CampaignOptions.sample_steps must be 0 (no sampling) or ≥ 2, got {self.sample_steps}",
        )
        _check(
            self.sample_walkers >= 2,
            f"CampaignOptions.sample_walkers must be ≥ 2, got {self.sample_walkers}",
        )
        _check(
            self.resimulations >= 1,
            f"CampaignOptions.resimulations must be ≥ 1, got {self.resimulations}",
        )

    @property
    def learned(self) -> bool:
        """Whether the fits use the learned likelihood (one learning per test point)."""
        return self.fit.likelihood == "learned"


@dataclasses.dataclass(frozen=True)
class ClusterOptions:
    """Where a campaign runs.

    scheduler : the address of a running dask scheduler (``tcp://host:8786``; e.g. of a
        dask-jobqueue or dask-kubernetes cluster); None starts a
        :class:`distributed.LocalCluster` of worker processes on this machine. Default None.
    workers : worker processes of the local cluster; None: one per core. Default None.
    cores_per_worker : JAX CPU devices each worker gives a fit (``rattlefit.configure``'s
        ``cpu_cores``); None: the cores divided among the local cluster's workers, or all
        of a worker machine's cores on a scheduler's cluster. Default None.
    compilation_cache : the directory of JAX's compiled programs that every worker shares
        (on a cluster, one every machine sees); True: ``$RATTLEFIT_CACHE_DIR`` or the
        default (:func:`rattlefit.use_compilation_cache`); False: none. Default True.
    dashboard : serve the local cluster's dashboard (on a free port). Default True.

    Raises :class:`~rattlefit.errors.RattlefitError` naming the option for a count below 1.
    """

    scheduler: str | None = None
    workers: int | None = None
    cores_per_worker: int | None = None
    compilation_cache: bool | str | os.PathLike[str] = True
    dashboard: bool = True

    def __post_init__(self):
        for name in ("workers", "cores_per_worker"):
            value = getattr(self, name)
            _check(
                value is None or value >= 1,
                f"ClusterOptions.{name} must be ≥ 1 or None, got {value}",
            )
        _check(
            self.scheduler is None or bool(str(self.scheduler).strip()),
            "ClusterOptions.scheduler must be an address such as tcp://host:8786, or None",
        )

    def local_workers(self) -> int:
        """The local cluster's worker count (``workers``, else one per core)."""
        return self.workers or max(1, os.cpu_count() or 1)

    def worker_cores(self) -> int | None:
        """The JAX devices each worker configures (None: its machine's cores)."""
        if self.cores_per_worker is not None or self.scheduler is not None:
            return self.cores_per_worker
        return max(1, (os.cpu_count() or 1) // self.local_workers())

    def cache(self) -> bool | str:
        """``compilation_cache`` as ``rattlefit.configure`` takes it (a path as text)."""
        if isinstance(self.compilation_cache, bool):
            return self.compilation_cache
        return os.fspath(self.compilation_cache)
