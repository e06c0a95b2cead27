"""The forward map of a fit: features of the problem's realisations at points in ``z``.

Every evaluation outside Levenberg–Marquardt's linear algebra goes through one compiled
program of :func:`chunk_size` rows (:func:`evaluate`), so the simulator compiles once per
fit and every stage sees the same realisations. On top of it: the residual and cost at a
batch of points, and finite-difference Jacobians of the ensemble-mean features (pathwise
derivatives of chaotic rattle grow like e^{λt} and are useless over a recording).
"""

from __future__ import annotations

from concurrent.futures import ThreadPoolExecutor

import equinox as eqx
import jax
import numpy as np

from ..quantities import DRAG_TORQUE
from ..util import array_namespace
from .problem import Problem


def fd_points(z, h, *, central: bool):
    """The points of a finite-difference Jacobian at ``z`` with steps ``h``: (1+P or 1+2P, P)."""
    xp = array_namespace(z, h)
    eye = xp.eye(z.shape[0])
    points = [z[None], z + h[:, None] * eye] + ([z - h[:, None] * eye] if central else [])
    return xp.concatenate(points)


def fd_jacobian(problem: Problem, z, h, feats, *, central: bool):
    """Residual at ``z`` and its finite-difference Jacobian from the ensemble-mean features
    ``feats`` (K, R, B) at :func:`fd_points`: forward differences when ``central`` is False,
    else central. The prior rows are differentiated exactly.
    """
    xp = array_namespace(z, h, feats, problem.sigma)
    p = z.shape[0]
    lower = feats[p + 1 :] if central else feats[0][None]
    d_mean = (feats[1 : p + 1] - lower) / ((2 if central else 1) * h[:, None, None])
    j_data = -(d_mean / xp.asarray(problem.sigma)[None]).reshape(p, -1).T
    jac = xp.concatenate([j_data, problem.prior_jacobian(z)])
    r = xp.concatenate([problem.data_rows(feats[0]), problem.prior_rows(z)])
    return r, jac


@eqx.filter_jit
def features_chunk(problem: Problem, rows):
    """:meth:`Problem.features_of_rows`, compiled (one program per problem structure)."""
    return problem.features_of_rows(rows)


#: Rows of every compiled evaluation: one block, run on one device. A lockstep step has a
#: fixed cost, so larger blocks cost less per member, but a block waits for its slowest
#: member; 24 (the realisations of one point in the covariance and profile stages) gives each
#: device one point. Results do not depend on the blocking only while every block has the
#: same row count (or one that XLA vectorises alike, a multiple of 4): XLA vectorises the step
#: over the rows and compiles other counts to code that rounds differently, which chaos grows
#: into another realisation.
CHUNK_ROWS = 24


def chunk_size() -> int:
    """Rows per round of evaluation over all local devices (one block of :data:`CHUNK_ROWS`
    each)."""
    return CHUNK_ROWS * len(jax.local_devices())


def evaluate(problem: Problem, zs, y0=None, realisations=None) -> np.ndarray:
    """Features of every realisation at each point of ``zs``: (K, R, M, B), numpy.

    Outside the Levenberg–Marquardt loop every evaluation goes through this one compiled
    program of :func:`chunk_size` rows (padded with repeats of the last row), so the
    simulator is compiled once however many points are asked for. ``realisations`` (indices)
    evaluates only those of the M (see :meth:`Problem.rows`): (K, R, len(realisations), B).

    A chunk waits for its slowest row, and the drag torque sets how often the gears impact
    and so how many steps a simulation takes: the points are simulated in the order of their
    drag torque, so that similar ones share a chunk (a row's features do not depend on the
    rows it shares a chunk with).
    """
    zs = np.atleast_2d(np.asarray(zs, dtype=float))
    m = problem.y0.shape[1] if y0 is None else y0.shape[1]
    if realisations is not None:
        m = len(realisations)
    order = np.argsort(zs[:, problem.index(DRAG_TORQUE)], kind="stable")
    rows = problem.rows(zs[order], None if y0 is None else np.asarray(y0), realisations)
    out = evaluate_rows(problem, rows).reshape(zs.shape[0], problem.n_rec, m, -1)
    return out[np.argsort(order)]


def evaluate_rows(problem: Problem, rows) -> np.ndarray:
    """Features (N, F), numpy, of ``rows`` in the layout of :meth:`Problem.rows` (point,
    recording, release state, dither, encoder phase; N rows), each simulated once.

    The rows are cut into blocks of :data:`CHUNK_ROWS` (the last padded with repeats of its
    last row), and block k runs on local device k mod D through the one compiled program of
    a block: the same program on every device, so a row's features depend neither on the
    rows it shares a block with nor on how many devices there are. Blocks are dispatched
    from one thread per device, so the devices (CPU cores or GPUs) work at once.
    """
    rows = [np.asarray(x) for x in rows]
    n, c = rows[0].shape[0], CHUNK_ROWS
    pad = -n % c
    rows = [np.concatenate([x, np.repeat(x[-1:], pad, axis=0)]) for x in rows]
    devices = jax.local_devices()
    starts = list(range(0, n + pad, c))

    def on_device(d: int) -> list[np.ndarray]:
        placed = jax.device_put(problem, devices[d])
        out = []
        for i in starts[d :: len(devices)]:
            block = jax.device_put(tuple(x[i : i + c] for x in rows), devices[d])
            out.append(np.asarray(features_chunk(placed, block)))
        return out

    # one thread per device: XLA releases the GIL while a block runs
    with ThreadPoolExecutor(len(devices)) as pool:
        per_device = list(pool.map(on_device, range(len(devices))))
    blocks = [per_device[k % len(devices)][k // len(devices)] for k in range(len(starts))]
    return np.concatenate(blocks)[:n]


def jacobian_at(problem: Problem, z) -> tuple[np.ndarray, np.ndarray]:
    """The fit's residual (data rows, then prior rows) at ``z`` and its forward-difference
    Jacobian (:func:`fd_jacobian`, steps towards the middle of each range so that no point
    leaves it), all 1 + P points simulated in one :func:`evaluate`."""
    z = np.asarray(z, dtype=float)
    h = np.asarray(problem.fd_steps(z))
    h = np.where(z > 0, -h, h)
    feats = np.asarray(problem.mean_of(evaluate(problem, fd_points(z, h, central=False))))
    r, jac = fd_jacobian(problem, z, h, feats, central=False)
    return np.asarray(r), np.asarray(jac)


def residuals(problem: Problem, zs, mean=None) -> np.ndarray:
    """The fit's residual (data rows, then prior rows) at each point of ``zs`` (K, P): (K, n),
    all simulated in one batched evaluation, so that the values are comparable; ``mean``
    (K, R, B) are the points' mean features if already simulated."""
    zs = np.atleast_2d(np.asarray(zs, dtype=float))
    if mean is None:
        mean = np.asarray(problem.mean_of(evaluate(problem, zs)))
    return np.stack(
        [
            np.concatenate([problem.data_rows(mean[k]), problem.prior_rows(zs[k])])
            for k in range(len(zs))
        ]
    )


def screen_features(problem: Problem, features, screen: str = "mean") -> np.ndarray:
    """The features (K, R, B) by which starting points are ranked, from their few screening
    realisations ``features`` (K, R, k, B) (``FitOptions.screen``).

    "mean": their mean in the regime kept (:meth:`Problem.mean_of`). "nearest": each
    start's realisation nearest the recording (in the band weights), recording by recording:
    near the truth of a recording in a rarer regime, one or two of every few releases reach
    it, and the mean of two realisations in different regimes matches neither, so the start
    would rank with the poor ones.
    """
    features = np.asarray(features)
    if screen == "mean":
        return np.asarray(problem.mean_of(features))
    data, sigma = np.asarray(problem.data), np.asarray(problem.sigma)
    d2 = np.sum(((features - data[None, :, None, :]) / sigma[None, :, None, :]) ** 2, axis=-1)
    nearest = np.argmin(d2, axis=2)  # (K, R)
    return np.take_along_axis(features, nearest[:, :, None, None], axis=2)[:, :, 0]


def costs(problem: Problem, zs, mean=None) -> np.ndarray:
    """The fit's cost (squared data and prior rows) at each point of ``zs`` (K, P)."""
    return np.sum(residuals(problem, zs, mean) ** 2, axis=1)
