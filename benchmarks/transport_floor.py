"""
The transport floor of a machine (``bench_machines.py --floor``): a node that moves the messages and computes nothing.

``python benchmarks/transport_floor.py kf_estimator --ros-args -r __ns:=/m1`` subscribes to the machine's
displacement and speed as the real kf_estimator does (same QoS, every block converted to numpy with the package's
``block_from_msg``) and publishes, per block, a bearing-displacement block (one channel per bearing and direction) and
an innovation block (one per probe) of zeros: the real node's traffic without its filter.  ``identifier`` only
receives.  Both run the executor the nodes run by default (:func:`bearing_id.nodes.process.make_executor`).  What the
three processes then cost is what any machine costs in this design (three processes, rclpy, one block topic), before
a single number is estimated.
"""
import os
import sys

os.environ.setdefault('OPENBLAS_NUM_THREADS', '1')

import numpy as np  # noqa: E402, I100  (after the thread setting above)
import rclpy  # noqa: E402
from rclpy.executors import ExternalShutdownException  # noqa: E402
from rclpy.node import Node  # noqa: E402
from rclpy.utilities import remove_ros_args  # noqa: E402

from bearing_id.config.params import load_rig, Probe  # noqa: E402, I100
from bearing_id.io import messages as M  # noqa: E402
from bearing_id.nodes.process import make_executor  # noqa: E402
from bearing_id.nodes.qos import qos_stream  # noqa: E402
from bearing_id.nodes.topics import (relative, TOPIC_BEARING_DISPLACEMENT, TOPIC_DISPLACEMENT,  # noqa: E402
                                     TOPIC_INNOVATION, TOPIC_SPEED)


class Floor(Node):
    """``kf_estimator``: receive and relay zeros of the real output's shape; ``identifier``: receive only."""

    def __init__(self, name: str):
        super().__init__(name)
        self.declare_parameter('executor', 'events')
        rig = load_rig()
        self.outputs = tuple(Probe(f'{b.name}_{d}', b.node, d) for b in rig.bearings for d in ('x', 'y'))
        self.relay = name == 'kf_estimator'
        if self.relay:
            self.pub_est = self.create_publisher(M.DisplacementBlock, relative(TOPIC_BEARING_DISPLACEMENT),
                                                 qos_stream())
            self.pub_nu = self.create_publisher(M.DisplacementBlock, relative(TOPIC_INNOVATION), qos_stream())
        self.create_subscription(M.DisplacementBlock, relative(TOPIC_DISPLACEMENT), self.on_block, qos_stream())
        self.create_subscription(M.RotorSpeed, relative(TOPIC_SPEED), lambda msg: None, qos_stream(50))

    def on_block(self, msg):
        b = M.block_from_msg(msg)
        if not self.relay:
            return
        n = b.samples.shape[0]
        for pub, probes in ((self.pub_est, self.outputs), (self.pub_nu, b.probes)):
            pub.publish(M.block_to_msg(
                samples=np.zeros((n, len(probes))), sequence=b.seq, sample_rate=b.sample_rate, speed=b.speed,
                angle=b.angle, probes=probes, stamp=b.stamp_ns, frame_id=b.frame_id, sample_angles=b.sample_angles,
                run_id=b.run_id))


def main() -> int:
    rclpy.init(args=sys.argv)
    node = Floor(remove_ros_args(sys.argv)[1])
    ex = make_executor(node)
    ex.add_node(node)
    try:
        while rclpy.ok():
            ex.spin_once(timeout_sec=0.25)
    except (KeyboardInterrupt, ExternalShutdownException):     # SIGINT / SIGTERM (rclpy's handlers)
        pass
    return 0


if __name__ == '__main__':
    sys.exit(main())
