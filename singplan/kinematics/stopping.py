"""Stopping distance: how far the TCP would still travel if the robot braked now (SEEDS 002's glide path).

Definition (per output sample, joints ``q`` [rad], velocities ``qd`` [rad/s]): every joint
brakes at once at its full deceleration ``a_j`` (the task's ``limits.acceleration``) from its
current speed and then stays at rest,

    q_j(t) = q_j + qd_j tau_j - 1/2 a_j sign(qd_j) tau_j^2,   tau_j = min(t, |qd_j| / a_j),

and the stopping distance is the length of the TCP path that motion traces until the last joint
stops, at ``T = max_j |qd_j| / a_j``. Each joint stops independently (the path is not kept while
braking, as in a category 1 stop at full deceleration), so the figure says how far the TCP would
sweep, not how far along the programmed path.

The length is ``integral_0^T |v(t)| dt`` with the TCP velocity v = J(q(t)) qd(t): the braking
time is cut into equal steps so that no joint turns more than :data:`BRAKE_STEP_RAD` in one (one
step for a slow motion, at most :data:`MAX_BRAKE_STEPS`), each step uses the Jacobian at its
middle, and the steps are cut again where a joint stops; on every piece the joint velocities are
then linear in t and the integral of |v| is taken in closed form (:func:`mean_norm`), so a TCP
velocity that turns or reverses while the joints stop at different times is followed exactly.
On random states of three arms (every joint at up to its speed limit, in any direction) the
figure is within 1 % of a 10 000-step polyline of forward kinematics (tests/test_stopping.py
holds it to that). The joint velocities are the trajectory's ``qd`` (central differences of the
samples); the cost is one batch of Jacobians per sample for slow motion (a few us a sample).

``singplan check`` times nothing, so it cannot compute this figure; it gives a bound instead, a
figure no sample of any plan of the task can exceed: from the joint paths a plan may follow and the
most any timing can speed them up (:func:`path_rates`, :func:`rest_speed_bounds`), the smaller of two
bounds, both derived in their docstrings: :func:`scaled_stopping_bound` (the figure at the top speed
along the path, plus what slower speeds could add) and :func:`stopping_bound` (joint by joint, from
each joint's reach :func:`reach_bounds`; it also serves where only the joints' speeds are known).
"""

from __future__ import annotations

import numpy as np

from singplan.kinematics.robot import Robot

BRAKE_STEP_RAD = 0.025  # the most a joint turns between two Jacobians of the braking motion ...
MAX_BRAKE_STEPS = 64  # ... up to this many (1.6 rad: a joint braking from 5.7 rad/s at 10 rad/s^2; longer steps beyond)
_CHUNK_VALUES = 62_500  # floats of per-piece Jacobians formed at once (0.5 MB; their temporaries take a few times that)
_CHUNK_ROWS = 8_192  # samples whose braking steps are counted at once (their temporaries ~1.6 MB)


def braking_joints(q: np.ndarray, qd: np.ndarray, acceleration_rad_s2: np.ndarray, t: np.ndarray) -> np.ndarray:
    """Joints (K, F, n) [rad] of samples q, qd (K, n) braking at ``acceleration_rad_s2`` (n,), at times t (K, F) [s]."""
    stop_s = np.abs(qd) / acceleration_rad_s2
    tau = np.minimum(t[:, :, None], stop_s[:, None, :])
    return q[:, None, :] + qd[:, None, :] * tau - 0.5 * (acceleration_rad_s2 * np.sign(qd))[:, None, :] * tau**2


def braking_velocities(qd: np.ndarray, acceleration_rad_s2: np.ndarray, t: np.ndarray) -> np.ndarray:
    """Joint velocities (K, F, n) [rad/s] of the braking samples qd (K, n) at times t (K, F) [s]."""
    left = np.maximum(np.abs(qd)[:, None, :] - acceleration_rad_s2 * t[:, :, None], 0.0)
    return np.sign(qd)[:, None, :] * left


def brake_steps(qd: np.ndarray, acceleration_rad_s2: np.ndarray) -> np.ndarray:
    """Jacobians per braking motion (K,) for samples qd (K, n): a power of two from 1 to
    :data:`MAX_BRAKE_STEPS`, so that no joint turns more than :data:`BRAKE_STEP_RAD` between two."""
    travel = np.max(qd**2 / (2.0 * acceleration_rad_s2), axis=1)  # the farthest any joint turns
    wanted = np.clip(np.ceil(travel / BRAKE_STEP_RAD), 1, MAX_BRAKE_STEPS)
    return (2 ** np.ceil(np.log2(wanted))).astype(np.int64)


def mean_norm(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """``integral_0^1 |a + (b - a) s| ds`` (...,) of 3-vectors a, b (..., 3), in closed form.

    With d = b - a the integrand is sqrt(|d|^2 x^2 + h^2), x = s + a.d / |d|^2 and h the distance of
    the line from the origin: ``|d| [F(x)]``, F(x) = (x r + k asinh(x / sqrt k)) / 2, r = sqrt(x^2 + k),
    k = (h / |d|)^2 (F = x |x| / 2 when the line passes through 0: the velocity reverses).
    Where d is tiny against a the speed hardly changes and Simpson's rule is exact enough.
    """
    d = b - a
    dd, ad, aa = (np.einsum("...i,...i->...", x, y) for x, y in ((d, d), (a, d), (a, a)))
    steady = dd <= 1e-6 * aa
    dd_safe = np.where(steady, 1.0, dd)
    x0 = ad / dd_safe
    k = np.maximum(aa / dd_safe - x0**2, 0.0)
    with np.errstate(divide="ignore", invalid="ignore"):
        def primitive(x: np.ndarray) -> np.ndarray:
            tail = np.where(k > 0.0, k * np.arcsinh(x / np.sqrt(k)), 0.0)
            return 0.5 * (x * np.sqrt(x**2 + k) + tail)
        exact = np.sqrt(dd_safe) * (primitive(x0 + 1.0) - primitive(x0))
    simpson = (np.linalg.norm(a, axis=-1) + 4.0 * np.linalg.norm(0.5 * (a + b), axis=-1)
               + np.linalg.norm(b, axis=-1)) / 6.0
    return np.where(steady, simpson, exact)


def stopping_distances(robot: Robot, q: np.ndarray, qd: np.ndarray, acceleration_rad_s2: np.ndarray) -> np.ndarray:
    """Stopping distance [m] (K,) of each sample q, qd (K, n), a bounded chunk of samples at a time
    (a sample at rest stops where it is: 0)."""
    n = q.shape[1]
    acc = np.broadcast_to(np.asarray(acceleration_rad_s2, dtype=float), (n,))
    out = np.zeros(len(q))
    for c in range(0, len(q), _CHUNK_ROWS):  # (brake_steps' temporaries take ~200 bytes a sample)
        speeds = qd[c:c + _CHUNK_ROWS]
        # a sample that is not a number keeps 0 (the final gate names it)
        moving = c + np.flatnonzero(np.any(speeds != 0.0, axis=1) & np.all(np.isfinite(speeds), axis=1))
        steps = brake_steps(qd[moving], acc)  # Jacobians of each moving sample's braking
        for m in np.flatnonzero(np.bincount(steps)).tolist():
            group = moving[steps == m]
            rows_per_chunk = max(1, _CHUNK_VALUES // ((m + n) * 3 * n))
            for k in range(0, len(group), rows_per_chunk):
                rows = group[k:k + rows_per_chunk]
                out[rows] = _braking_lengths(robot, q[rows], qd[rows], acc, m)
    return out


def _braking_lengths(robot: Robot, q: np.ndarray, qd: np.ndarray, acc: np.ndarray, m: int) -> np.ndarray:
    """TCP path lengths [m] (K,) of the braking motions of samples q, qd (K, n) with m Jacobians each.

    The braking time [0, T] is cut into m equal steps, each with the Jacobian at its middle, and
    further at every joint's stop time (where its velocity stops falling): on each piece the joint
    velocities are linear in t, so with the step's Jacobian the TCP velocity is linear too and
    :func:`mean_norm` integrates its magnitude exactly.
    """
    k_rows = len(q)
    stop_s = np.abs(qd) / acc
    T = stop_s.max(axis=1)
    step = T[:, None] * (np.arange(m + 1) / m)  # (K, m + 1)
    J = robot.tcp_jacobians(braking_joints(q, qd, acc, 0.5 * (step[:, :-1] + step[:, 1:])).reshape(-1, q.shape[1]))
    J = J.reshape(k_rows, m, 3, q.shape[1])
    cuts = np.sort(np.concatenate([step, stop_s], axis=1), axis=1)  # (K, m + 1 + n)
    t0, t1 = cuts[:, :-1], cuts[:, 1:]
    which = np.minimum((0.5 * (t0 + t1) / np.where(T > 0, T, 1.0)[:, None] * m).astype(np.int64), m - 1)
    J_piece = J[np.arange(k_rows)[:, None], which]  # (K, P, 3, n)
    v0 = np.einsum("kpij,kpj->kpi", J_piece, braking_velocities(qd, acc, t0))
    v1 = np.einsum("kpij,kpj->kpi", J_piece, braking_velocities(qd, acc, t1))
    return np.sum((t1 - t0) * mean_norm(v0, v1), axis=1)


def worst_stopping(distances_m: np.ndarray, t: np.ndarray) -> tuple[float, float]:
    """The worst stopping distance [mm] and when [s] (trajectory.json's metrics); ``t``: the
    sample times (K,)."""
    k = int(np.argmax(distances_m)) if len(distances_m) else 0
    worst = float(distances_m[k]) if len(distances_m) else 0.0
    return worst * 1e3, float(t[k]) if len(t) else 0.0


def reach_bounds(robot: Robot) -> np.ndarray:
    """rho_bar (n,) [m]: for each chain joint j, a bound on the TCP's distance from joint j's axis in
    every configuration. From joint j's origin the TCP is at ``t_(j+1) + R (rest of the chain)``;
    joint j's own turn keeps the distance from its axis, so the first link counts by its part across
    the axis and every later link (and the tool) by its length (the triangle inequality: a link keeps
    its length whatever the joints do). A forearm along axis 4 thus adds nothing to axis 4's reach."""
    model = robot.model
    tool = (model.frames[robot.tip_frame_id].placement * robot.T_tip_tcp).translation
    links = [np.asarray(model.jointPlacements[k].translation) for k in range(2, model.njoints)] + [tool]
    lengths = np.append(robot.link_lengths_m[2:], np.linalg.norm(tool))  # link j + 1 .. n, then the tool
    # every suffix at once, summed from the tool inwards (Robot.offsets_m sums the other way: a last bit apart)
    after = np.concatenate([np.cumsum(lengths[::-1])[::-1][1:], [0.0]])  # the links beyond the first
    across = [float(np.linalg.norm(v - np.dot(v, a) * a)) for v, a in zip(links, robot.joint_axes, strict=True)]
    return np.array(across) + after


def stopping_bound(robot: Robot, q: np.ndarray, speed_rad_s: np.ndarray, acceleration_rad_s2: np.ndarray,
                   moved_rad: np.ndarray | None = None) -> np.ndarray:
    """An upper bound [m] (N,) of :func:`stopping_distances` over every state (q', qd) with
    ``|qd_j| <= speed_rad_s[k, j]`` and ``|q'_j - q_kj| <= moved_rad[j]`` (n,) (default 0), for joint
    samples q (N, n) and speed bounds (N, n) [rad/s].

    Derivation. While braking, joint j turns ``|qd_j(t)|`` from its speed down to 0 and travels
    ``delta_j = qd_j^2 / (2 a_j)`` in all. The TCP velocity is ``v = sum_j J_j(q(t)) qd_j(t)``, whose
    column j (a revolute joint) has the length of ``z_j x (p - o_j)``: the TCP's distance from axis j,
    ``d_j(q(t))``. The triangle inequality gives

        D = integral |v| dt <= sum_j integral d_j(q(t)) |qd_j(t)| dt <= sum_j rho_j delta_j,

    with rho_j any bound of d_j along the braking motion. d_j depends only on the joints after j
    (joint j turns the TCP about its own axis; the joints before it move both rigidly), and turning
    joint k by an angle moves the TCP, in joint j's frame, along arcs no longer than
    ``rho_bar_k`` times that angle (:func:`reach_bounds`), so

        rho_j = d_j(q) + sum_{k > j} rho_bar_k delta_k

    (plus ``rho_bar_k moved_k`` for a state displaced from q by up to ``moved_rad``).

    Each term grows with |qd_j|, so the bound at the speed bounds holds for every slower state,
    whatever the joints' directions and the time law. It is loose where joints cancel at the TCP
    (a swinging wrist whose axes 4 and 6 nearly align), and within a factor of about 1.2 - 3 of the
    figure where the joints follow a path at speed (measured: tests/test_stopping.py).
    """
    acc = np.broadcast_to(np.asarray(acceleration_rad_s2, dtype=float), (q.shape[1],))
    delta = speed_rad_s**2 / (2.0 * acc)  # (N, n) [rad]
    shift = np.zeros(q.shape[1]) if moved_rad is None else np.asarray(moved_rad, dtype=float)
    out = np.empty(len(q))
    rho_bar = reach_bounds(robot)
    rows = max(1, _CHUNK_VALUES // (4 * q.shape[1]))
    for c in range(0, len(q), rows):
        d = np.linalg.norm(robot.tcp_jacobians(q[c:c + rows]), axis=1)  # (K, n) [m]: TCP from each axis
        moved = np.cumsum((rho_bar * (delta[c:c + rows] + shift))[:, ::-1], axis=1)[:, ::-1]  # sum over k >= j
        after = np.concatenate([moved[:, 1:], np.zeros((len(d), 1))], axis=1)  # sum over k > j
        out[c:c + rows] = np.sum(delta[c:c + rows] * (d + after), axis=1)
    return out


def path_rates(s: np.ndarray, q: np.ndarray, velocity_rad_s: np.ndarray,
               rate_cap: np.ndarray | None = None) -> tuple[np.ndarray, np.ndarray]:
    """The slopes dq/ds (N, n) of a joint path q(s) at its samples (s (N,), q (N, n)), and the most
    ds/dt (N,) any timing within the joint speed limits ``velocity_rad_s`` (n,) and within ``rate_cap``
    (N,) (the TCP speed; None: no cap) can have there: ``min(rate_cap, min_k velocity_k / |dq_k/ds|)``.

    A timing of the path moves the joints at ``qd = (dq/ds) ds/dt``: in the slopes' direction, at
    most at that rate. The slopes are finite differences of the samples; between two samples the
    rate is held to the larger of the two.
    """
    slopes = np.gradient(q, s, axis=0) if len(s) > 1 else np.zeros_like(q)
    rate = _rate(np.abs(slopes), velocity_rad_s)
    if rate_cap is not None:
        rate = np.minimum(rate, rate_cap)
    rate[1:] = np.maximum(rate[1:], rate[:-1])
    rate[:-1] = np.maximum(rate[:-1], rate[1:])
    return slopes, rate


def _rate(slopes: np.ndarray, speed_rad_s: np.ndarray) -> np.ndarray:
    """min over joints of speed / |slope| (N,) for slopes (N, n) and speeds (n,) or (N, n); inf where nothing moves."""
    with np.errstate(divide="ignore", invalid="ignore"):
        return np.min(np.where(slopes > 0, speed_rad_s / slopes, np.inf), axis=1)


def capped_rates(slopes: np.ndarray, rate: np.ndarray, speed_rad_s: np.ndarray) -> np.ndarray:
    """``rate`` (N,) lowered where a joint would pass its speed bound ``speed_rad_s`` (N, n) at it."""
    return np.minimum(rate, _rate(np.abs(slopes), speed_rad_s))


def scaled_stopping_bound(robot: Robot, q: np.ndarray, qd: np.ndarray, acceleration_rad_s2: np.ndarray) -> np.ndarray:
    """An upper bound [m] (N,) of :func:`stopping_distances` over the states (q_k, c qd_k), 0 <= c <= 1:
    a joint path followed at any speed up to qd (N, n) in its direction.

    Derivation. Braking from (q, c qd) traces the joint path ``q + lambda Delta(s)``, ``lambda = c^2``,
    where Delta(s) is the braking of c = 1 at normalised time s (every joint's braking scales as
    ``c^2`` in position and c in time). Its TCP length is ``L(lambda) = lambda f(lambda)``,
    ``f(lambda) = integral |J(q + lambda Delta) Delta'| ds``. The linear Jacobian's column j changes
    with joint k at most at ``L_jk`` = rho_bar_j (k < j: the column turns with joint k) or
    rho_bar_k (k >= j) per radian (:func:`reach_bounds`), and joint k is at most delta_k =
    qd_k^2 / (2 a_k) from where it starts, so ``f(lambda) <= f(1) + (1 - lambda) M`` with
    ``M = sum_jk L_jk delta_j delta_k``. Hence ``L(lambda) <= lambda L(1) + lambda (1 - lambda) M``,
    whose largest value on [0, 1] is L(1) when M <= L(1), else ``(L(1) + M)^2 / (4 M)``. L(1) is the
    figure at qd (:func:`stopping_distances`, within 1 % of the integral: taken 1 % higher).
    """
    acc = np.broadcast_to(np.asarray(acceleration_rad_s2, dtype=float), (q.shape[1],))
    full = 1.01 * stopping_distances(robot, q, qd, acc)
    delta = qd**2 / (2.0 * acc)  # (N, n)
    rho_bar = reach_bounds(robot)
    n = q.shape[1]
    jk = np.where(np.arange(n)[None, :] < np.arange(n)[:, None], rho_bar[:, None], rho_bar[None, :])  # L_jk
    M = np.einsum("nj,jk,nk->n", delta, jk, delta)
    with np.errstate(divide="ignore", invalid="ignore"):
        return np.where(full >= M, full, (full + M) ** 2 / (4.0 * np.where(M > 0, M, 1.0)))


def rest_speed_bounds(travel_rad: np.ndarray, acceleration_rad_s2: np.ndarray, period_s: float) -> np.ndarray:
    """Joint speed bounds [rad/s] (like ``travel_rad``, (..., n)) of joints ``travel_rad`` [rad] of
    joint path away from a point where they are at rest (the total turning since it, or until it).

    From rest, ``d(qd^2)/dt = 2 qd qdd <= 2 a |qd|``, so ``qd^2 <= 2 a integral |qd| dt``: a joint
    cannot be faster than ``sqrt(2 a travel)`` (a short move never reaches its cruise speed). The
    samples' differences see the acceleration one period late: ``a * period`` is added.
    """
    acc = np.asarray(acceleration_rad_s2, dtype=float)
    return np.sqrt(2.0 * acc * np.maximum(travel_rad, 0.0)) + acc * period_s


def travel(q: np.ndarray) -> np.ndarray:
    """Each joint's total turning [rad] from the first sample to each sample of q (N, n): (N, n)."""
    steps = np.abs(np.diff(q, axis=0))
    return np.concatenate([np.zeros((1, q.shape[1])), np.cumsum(steps, axis=0)])

