"""
Defaults shared by the command line and the nodes: each number lives here once, with its unit and its reason.

``bearing-id identify`` and the identifier node cut steady windows, fit their 1X vectors and pick the method by
these values; the Kalman filter's process noise is the same for the paper method offline and live, and for the
kf_estimator node. Every node parameter file (``params/<node>.yaml``) is generated from specs that take their
defaults from here.
"""
METHOD = 'auto'             # identification method: chosen by what the data determine (bearing_id.identify.auto)
KF_PROCESS_NOISE = 1e-16    # Q, process noise variance per filter step x identity [m^2, (m/s)^2]; paper: 1e-16..1e-18
SPEED_TOLERANCE = 0.005     # relative speed change that ends a steady window; also matches speeds across runs [-]
SETTLE_FRACTION = 0.25      # fraction of each steady window discarded at its start (the transient after a step) [-]
MIN_WINDOW = 0.2            # s: the shortest steady window whose 1X vector is fitted
TRANSIENTS = 3              # decaying modes (the rotor ringing after a speed change) fitted jointly with the 1X
MAX_WINDOW = 120.0          # s: a longer steady window is fitted in pieces of this length, then combined (memory)
# change detection on the history (bearing-id trend and the identifier's live alarms: the same CUSUM)
ALARM_ARL0 = 10000.0        # points (solves) to a false alarm, per parameter series: ~1 a year at one solve an hour
ALARM_SHIFT = 2.0           # sigma: the shift the CUSUM detects fastest
ALARM_REFERENCE = 10        # points: the first N of each series (and after each alarm) are its in-control reference
