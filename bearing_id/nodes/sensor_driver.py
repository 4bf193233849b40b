"""
``sensor_driver``: publishes what a DAQ on the rig would: displacement blocks, rotor speed, the known excitation.

Sources (the simulated rig or DAQ exports, one recording per excitation run) and the message stream are
:mod:`bearing_id.nodes.sensor_driver_core`; this module paces the blocks in real time times ``rate_factor``.

Topics
    ``/rotor/displacement`` (DisplacementBlock, ``block_size`` samples; sequence +1 per block across runs; stamps
    continuous across runs, wall time of the first sample), ``/rotor/speed`` (RotorSpeed, one per block),
    ``/rotor/excitation`` (Excitation, latched; sent at each run change, stamped with the run's first block),
    ``/rotor/oil_temperature`` (sensor_msgs/Temperature, degC, every ``oil_temperature_interval`` of stream time,
    when the sim source has an oil temperature: ``oil_temperature_mean``).
    QoS: see :mod:`bearing_id.nodes.qos`.
"""
from __future__ import annotations

import sys
import threading
import time

from diagnostic_msgs.msg import DiagnosticArray
from rclpy.node import Node
from sensor_msgs.msg import Temperature

from .declare import declare_parameters
from .diagnostics import diagnostics_msg
from .machine import label, machine_id
from .process import run_node
from .qos import qos_latched, qos_stream, stream_depth
from .sensor_driver_core import (blocks_total, load_sources, NAME, opened, Prefetch, sim_temperature, SPECS,
                                 stream_messages)
from .status import DiagItem, ERROR, OK, WARN
from .topics import relative, TOPIC_DISPLACEMENT, TOPIC_EXCITATION, TOPIC_OIL_TEMPERATURE, TOPIC_SPEED
from ..io import messages as M


PREFETCH_SECONDS = 4.0     # s of stream computed or read ahead of the real-time pacing


class SensorDriver(Node):
    """The sensor_driver node: publishes its source's blocks, speed and excitation in real time x rate_factor."""

    def __init__(self):
        super().__init__(NAME)
        v = declare_parameters(self, SPECS)
        self.values = v
        self.sources = load_sources(v)       # files: a list; sim: a plan that builds each run when its turn comes
        first = opened(self.sources[0])      # a first file that cannot be read: a clear error, exit 2
        if isinstance(self.sources, list):
            self.sources[0] = first          # the file just read streams from memory, not read twice
        self.sample_rate = first.sample_rate
        self._prefetch = None
        self.machine = machine_id(v['machine_id'], self.get_namespace())
        self.frame_id = v['frame_id'] or label(self.machine, first.rig_name)
        self.blocks_total = blocks_total(self.sources, v['block_size'])
        self.skipped = []        # (source, reason) of runs that could not be streamed
        self.pub_disp = self.create_publisher(M.DisplacementBlock, relative(TOPIC_DISPLACEMENT),
                                              qos_stream(stream_depth(self.sample_rate, v['block_size'])))
        self.pub_speed = self.create_publisher(M.RotorSpeed, relative(TOPIC_SPEED), qos_stream(50))
        self.pub_exc = self.create_publisher(M.Excitation, relative(TOPIC_EXCITATION), qos_latched())
        self.pub_diag = self.create_publisher(DiagnosticArray, '/diagnostics', 10)
        self.temperature = sim_temperature(v)
        self.pub_temp = self.create_publisher(Temperature, relative(TOPIC_OIL_TEMPERATURE), qos_stream(50))
        self.sent = 0
        self.late = 0            # blocks published later than their real-time slot by > one block
        self.state = 'waiting for subscribers'
        self.finished = False
        self._stop = threading.Event()
        self.create_timer(v['diagnostics_period'], self._diagnostics)
        self._thread = threading.Thread(target=self._publish_loop, name='sensor_driver_pub', daemon=True)
        self._thread.start()
        what = (f'{len(self.sources)} simulated run(s), {self.blocks_total} blocks' if v['source'] == 'sim' else
                f'{len(self.sources)} file(s), each read when its turn comes')
        self.get_logger().info(f"source {v['source']}: {what}, rate factor {v['rate_factor']:g}")

    def _publish_loop(self):
        v = self.values
        t_wait = time.monotonic()
        while (self.pub_disp.get_subscription_count() < v['wait_for_subscribers']
               and time.monotonic() - t_wait < v['subscriber_timeout'] and not self._stop.is_set()):
            time.sleep(0.05)
        if self._stop.is_set():
            return
        self.state = 'publishing'
        t0_wall = time.monotonic()
        base_ns = self.get_clock().now().nanoseconds
        rate = v['rate_factor']
        pubs = {TOPIC_DISPLACEMENT: self.pub_disp, TOPIC_SPEED: self.pub_speed, TOPIC_EXCITATION: self.pub_exc,
                TOPIC_OIL_TEMPERATURE: self.pub_temp}
        # computed (sim) or read (files) up to PREFETCH_SECONDS of stream ahead of the real-time pacing (3 messages
        # per block: speed, displacement, an excitation now and then)
        ahead = 3 * max(1, int(PREFETCH_SECONDS * self.sample_rate / v['block_size']))
        self._prefetch = Prefetch(stream_messages(self.sources, v['block_size'], base_ns, self.frame_id,
                                                  on_skip=self._skip, temperature=self.temperature,
                                                  temperature_interval=v['oil_temperature_interval']), ahead)
        for topic, t_ns, msg, end_ns in self._prefetch:
            if self._stop.is_set():
                return
            if topic == TOPIC_EXCITATION:
                self.state = f'publishing run {msg.run_id}'
            elif topic == TOPIC_DISPLACEMENT:
                # a block goes out when its last sample would have been acquired
                delay = t0_wall + (end_ns - base_ns) * 1e-9 / rate - time.monotonic()
                if delay > 0:
                    self._stop.wait(delay)
                elif -delay > (end_ns - t_ns) * 1e-9 / rate:
                    self.late += 1
                self.sent += 1
            pubs[topic].publish(msg)
        self.state = 'done'
        self.get_logger().info(f'published all {self.sent} blocks ({self.late} late)')
        self._diagnostics()
        if v['exit_when_done']:
            time.sleep(0.5)          # let reliable QoS deliver the tail
            self.finished = True

    def _skip(self, source, reason):
        """Log a run that cannot be streamed (unreadable file, other sample rate); /diagnostics names it."""
        self.skipped.append((getattr(source, 'path', str(source)), reason))
        self.get_logger().error(f'skipped {self.skipped[-1][0]}: {reason}')

    def _diagnostics(self):
        problems = []
        if self.late:
            problems.append(f'{self.late} block(s) published late (machine too slow for rate_factor '
                            f"{self.values['rate_factor']})")
        if self.skipped:
            problems.append(f'{len(self.skipped)} run(s) skipped: ' +
                            '; '.join(f'{name}: {why}' for name, why in self.skipped))
        level = ERROR if self.skipped else WARN if self.late else OK
        item = DiagItem(f'{NAME}: source', level, '; '.join([self.state] + problems), {
            'source': self.values['source'], 'blocks_sent': self.sent,
            'blocks_total': 'unknown until every file is read' if self.blocks_total is None else self.blocks_total,
            'late_blocks': self.late, 'skipped_runs': len(self.skipped),
            'subscribers': self.pub_disp.get_subscription_count()})
        self.pub_diag.publish(diagnostics_msg([item], self.get_clock().now().to_msg(), self.frame_id, self.machine))

    def close(self):
        self._stop.set()
        self._thread.join(timeout=2.0)
        if self._prefetch is not None:
            self._prefetch.close()


def main(argv=None) -> int:
    return run_node(NAME, 'Publish displacement blocks, rotor speed and the known excitation from the simulated '
                          'rig or from DAQ export files (SI units: m, rad/s, rad).', SPECS, SensorDriver, argv)


if __name__ == '__main__':  # pragma: no cover
    sys.exit(main())
