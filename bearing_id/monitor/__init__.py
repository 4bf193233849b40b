"""
Condition monitoring without ROS: sequential change detection on identified physical parameters.

* :mod:`.cusum` -- the two-sided tabular CUSUM on a standardised sequence, its threshold from the average run length
  to a false alarm (Siegmund's approximation), alarms with onset, size and its sigma, and the evidence.
"""
