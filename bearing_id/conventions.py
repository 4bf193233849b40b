"""
The one place where bearing_id fixes its signs, axes, phases, node numbers and units.

Everything else imports from here; tests in ``test/test_conventions.py`` pin each rule.

Axes and rotation
    x horizontal, y vertical (up), z along the shaft from the non-drive end; gravity acts along -y.
    The shaft spins from +x towards +y (counter-clockwise seen from +z looking back at the origin).
    Forward whirl is an orbit that turns the same way as the shaft (+x -> +y).

Degrees of freedom
    4 per node, ordered ``[x, y, theta_x, theta_y]`` with theta_x = -dy/dz (rotation about x) and
    theta_y = +dx/dz (rotation about y); the same as Nelson (1980) and ROSS's lateral subset
    ``[x, y, alpha, beta]``.  Global DOF index = 4 * (node - 1) + local index.

Node numbers
    1-based in files, messages, reports and the command line (as in the paper: bearings at nodes 2 and 10);
    0-based only inside arrays.  :func:`node_index` is the single conversion.

Equation of motion (SI units: m, kg, s, N, rad)
    M q'' + (C + Omega G) q' + K q = f,  with Omega the spin speed [rad/s] and G the gyroscopic matrix
    (skew-symmetric; with this sign forward-whirl frequencies rise with speed).

Bearing force on the shaft
    f = -K q - C q',  K [N/m] and C [N s/m] as 2x2 blocks ``[[xx, xy], [yx, yy]]`` on (x, y) of the bearing node.
    Flat order everywhere (messages, JSON, arrays): ``xx, xy, yx, yy``.

Bearing-literature frame
    Journal-bearing formulas (Ocvirk, Lund) use X along the static load and Y 90 deg ahead in the spin
    direction.  With the load along -y and spin +x -> +y, X_lit = -y and Y_lit = +x; :func:`lit_to_xy`
    maps 2x2 coefficient blocks from that frame into ours.

Phasors and phase reference
    x(t) = Re{X exp(j phi(t))} where phi(t) is the rotor angle measured from the keyphasor mark
    (phi = 0 when the key mark passes the keyphasor probe; phi = Omega t at constant speed).
    Phase angles reported to people are arg(X) in degrees; all other angles are radians.
    Keyphasor pulse: phi = 0 when the pulse's rising edge crosses 50 % of its low-to-high swing; a square (TTL)
    keyphasor is high while phi mod 2 pi is in [0, width), so a sample exactly on the mark is high
    (bearing_id.signals.keyphasor rebuilds phi from a sampled pulse; KEY_MARK_CONVENTION there).
    Streams carry phi of every sample (DisplacementBlock.sample_angles); the speed of a sample is the forward
    difference of phi (bearing_id.signals.windows.speed_from_angle).

Probe directions (measurement rows)
    A displacement probe at angle a in the x-y plane (a measured from +x towards +y, i.e. in the spin direction;
    x = 0 deg, y = 90 deg; API 670's pair at +-45 deg from vertical is a = 45 deg and a = 135 deg) with gain g reads
    g (cos(a) x + sin(a) y) of its node: :func:`probe_row`.  A probe's ``direction`` text carries both:
    'x' and 'y' (unit gain; rows exactly (1, 0) and (0, 1)), or '<a>deg' (e.g. '45deg', '-45deg'), each optionally
    followed by '*<g>' ('x*0.98', '135deg*1.02').  :func:`probe_direction` writes it, :func:`parse_probe_direction`
    reads it (exact round trip of the floats); messages, .npz files and reports carry this text per channel.

Gravity and static loads
    Gravity is a vector in the x-y plane (default (0, -GRAVITY)); a bearing's static load is the film force on the
    journal that carries the rotor, along -gravity unless given as a vector (Fx, Fy) [N].  A plain journal bearing's
    coefficients for a load along an arbitrary direction are those for a load along -y rotated by
    :func:`load_rotation` (the bearing is axisymmetric).

Unbalance
    A mass-radius product ``me`` [kg m] at angle ``phase`` [rad] from the key mark (in the spin direction)
    gives the rotating force f = me Omega^2 [cos(phi + phase), sin(phi + phase)], i.e. phasors
    Fx = me Omega^2 exp(j phase), Fy = -j Fx.

Units at the edges
    rpm, micrometres and degrees only where a person reads (:func:`rpm_to_rad_s`, :func:`rad_s_to_rpm`).
"""
from __future__ import annotations

import math

import numpy as np

DOF_PER_NODE = 4
LOCAL_DOF = {'x': 0, 'y': 1, 'tx': 2, 'ty': 3}
COEFF_ORDER = ('xx', 'xy', 'yx', 'yy')
GRAVITY = 9.80665  # m/s^2, acts along -y

RPM_PER_RAD_S = 60.0 / (2.0 * math.pi)


def node_index(node: int, n_nodes: int | None = None) -> int:
    """1-based node number -> 0-based array index; raises ValueError on nonsense."""
    if isinstance(node, bool) or int(node) != node:
        raise ValueError(f'node numbers are whole numbers, got {node!r}')
    node = int(node)
    if node < 1:
        raise ValueError(f'node numbers are 1-based (first node is 1), got {node}')
    if n_nodes is not None and node > n_nodes:
        raise ValueError(f'node {node} does not exist: the model has nodes 1..{n_nodes}')
    return node - 1


def dof_index(node: int, direction: str, n_nodes: int | None = None) -> int:
    """Global 0-based DOF index of ``direction`` ('x', 'y', 'tx', 'ty') at 1-based ``node``."""
    if direction not in LOCAL_DOF:
        raise ValueError(f'direction must be one of {sorted(LOCAL_DOF)}, got {direction!r}')
    return DOF_PER_NODE * node_index(node, n_nodes) + LOCAL_DOF[direction]


def rpm_to_rad_s(rpm):
    """Speed in rev/min -> rad/s (scalar or array)."""
    return np.asarray(rpm, dtype=float) / RPM_PER_RAD_S if np.ndim(rpm) else float(rpm) / RPM_PER_RAD_S


def rad_s_to_rpm(speed):
    """Speed in rad/s -> rev/min (scalar or array)."""
    return np.asarray(speed, dtype=float) * RPM_PER_RAD_S if np.ndim(speed) else float(speed) * RPM_PER_RAD_S


def unbalance_phasors(me: float, phase: float, speed: float) -> tuple[complex, complex]:
    """Force phasors (Fx, Fy) [N] of an unbalance ``me`` [kg m] at ``phase`` [rad] spinning at ``speed`` [rad/s]."""
    fx = me * speed**2 * np.exp(1j * phase)
    return complex(fx), complex(-1j * fx)


def force_phasors(magnitude: float, phase: float, direction: str) -> tuple[complex, complex]:
    """
    Force phasors (Fx, Fy) [N] of a directional force of ``magnitude`` [N] and ``phase`` [rad].

    ``direction`` is 'x' or 'y' (a shaker along one axis) or 'forward'/'backward' (a rotating force).
    """
    f = magnitude * np.exp(1j * phase)
    if direction == 'x':
        return complex(f), 0j
    if direction == 'y':
        return 0j, complex(f)
    if direction == 'forward':
        return complex(f), complex(-1j * f)
    if direction == 'backward':
        return complex(f), complex(1j * f)
    raise ValueError(f"force direction must be 'x', 'y', 'forward' or 'backward', got {direction!r}")


def phasor_to_time(X, angle):
    """Time signal Re{X exp(j angle)}; ``angle`` is the rotor angle [rad] times the harmonic order."""
    return np.real(np.asarray(X)[..., None] * np.exp(1j * np.asarray(angle))) if np.ndim(X) else np.real(
        X * np.exp(1j * np.asarray(angle)))


def whirl_direction(X: complex, Y: complex) -> str:
    """'forward' or 'backward' for the orbit with phasors (X, Y) (x(t) = Re{X e^{jwt}}, same for y)."""
    # z = x + j y = (X + jY)/2 e^{j phi} + conj((X - jY)/2) e^{-j phi}: the first term turns +x -> +y
    forward = abs(X + 1j * Y) / 2
    backward = abs(X - 1j * Y) / 2
    return 'forward' if forward >= backward else 'backward'


def orbit_semi_axes(X: complex, Y: complex) -> tuple[float, float]:
    """
    Semi-major and semi-minor axes [same unit as X] of the elliptical orbit with phasors (X, Y).

    The orbit is the sum of a forward circle of radius |X + jY|/2 and a backward one of radius |X - jY|/2.
    """
    f = abs(X + 1j * Y) / 2
    b = abs(X - 1j * Y) / 2
    return f + b, abs(f - b)


def probe_direction(angle_deg: float = 0.0, gain: float = 1.0) -> str:
    """
    Return the direction text of a probe at ``angle_deg`` [deg, from +x towards +y] with ``gain`` [-].

    'x' / 'y' for 0 / 90 deg (the text of a v1 probe), else '<angle>deg'; '*<gain>' appended unless the gain is 1.
    """
    a, g = float(angle_deg), float(gain)
    if not (math.isfinite(a) and math.isfinite(g) and g != 0.0):
        raise ValueError(f'a probe needs a finite angle and a finite non-zero gain, got {a!r} deg, gain {g!r}')
    text = 'x' if a == 0.0 else 'y' if a == 90.0 else f'{a!r}deg'
    return text if g == 1.0 else f'{text}*{g!r}'


def direction_words(direction: str) -> str:
    """
    Return a probe direction ('x', 'y', '45deg', '135deg*1.02', ...) in words for a person.

    'horizontal (x)' at 0 deg, 'vertical (y)' at 90 deg, else 'at <angle>° from +x towards +y' (the gain is not
    part of the direction).
    """
    angle = parse_probe_direction(direction)[0]
    if angle == 0.0:
        return 'horizontal (x)'
    if angle == 90.0:
        return 'vertical (y)'
    return f'at {angle:g}° from +x towards +y'


def parse_probe_direction(direction: str) -> tuple[float, float]:
    """
    Return (angle [deg], gain [-]) of a probe direction text ('x', 'y', '45deg', '135deg*1.02', ...).

    Raises ValueError for anything else.
    """
    text = str(direction).strip()
    head, star, tail = text.partition('*')
    try:
        gain = float(tail) if star else 1.0
        if head == 'x':
            angle = 0.0
        elif head == 'y':
            angle = 90.0
        elif head.endswith('deg'):
            angle = float(head[:-3])
        else:
            raise ValueError(head)
    except ValueError:
        raise ValueError(f"probe direction must be 'x', 'y' or '<angle>deg' (optionally '*<gain>'), got "
                         f'{direction!r}') from None
    if not (math.isfinite(angle) and math.isfinite(gain) and gain != 0.0):
        raise ValueError(f'probe direction {direction!r}: angle and gain must be finite, gain non-zero')
    return angle, gain


def probe_row(direction) -> tuple[float, float]:
    """
    Return the measurement row (cx, cy) of a probe: it reads cx x + cy y of its node [m/m].

    ``direction`` is a direction text (see :func:`parse_probe_direction`) or an angle in degrees.  'x' gives exactly
    (1, 0) and 'y' exactly (0, 1); otherwise gain (cos a, sin a).
    """
    if isinstance(direction, str):
        if direction == 'x':
            return 1.0, 0.0
        if direction == 'y':
            return 0.0, 1.0
        angle, gain = parse_probe_direction(direction)
    else:
        angle, gain = float(direction), 1.0
    if angle % 360.0 == 0.0:
        c, s = 1.0, 0.0
    elif angle % 360.0 == 90.0:
        c, s = 0.0, 1.0
    elif angle % 360.0 == 180.0:
        c, s = -1.0, 0.0
    elif angle % 360.0 == 270.0:
        c, s = 0.0, -1.0
    else:
        a = math.radians(angle)
        c, s = math.cos(a), math.sin(a)
    return gain * c, gain * s


def load_rotation(load_vector) -> np.ndarray:
    """
    Return the rotation R (2x2) taking the film force (0, W) to ``load_vector`` = (Fx, Fy) [N], W = |load_vector|.

    Coefficients of an axisymmetric bearing under that load are ``R K R^T`` and ``R C R^T`` of those for (0, W).
    """
    fx, fy = (float(v) for v in load_vector)
    w = math.hypot(fx, fy)
    if not w > 0:
        raise ValueError(f'a load vector needs a non-zero magnitude, got ({fx}, {fy}) N')
    # columns: where (1, 0) and (0, 1) go; (0, 1) -> (fx, fy) / w
    return np.array([[fy / w, fx / w], [-fx / w, fy / w]])


# Rotation from our (x, y) to the bearing-literature frame (X along load = -y, Y = +x): q_lit = T q.
_T_LIT = np.array([[0.0, -1.0], [1.0, 0.0]])


def lit_to_xy(block_lit: np.ndarray) -> np.ndarray:
    """
    Map a 2x2 coefficient block from the bearing-literature frame (X = load, Y = 90 deg ahead) to (x, y).

    Force and displacement transform alike: f_lit = T f, q_lit = T q, so K_xy = T^T K_lit T.
    """
    return _T_LIT.T @ np.asarray(block_lit, dtype=float) @ _T_LIT
