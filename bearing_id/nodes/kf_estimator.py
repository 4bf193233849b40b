"""
``kf_estimator``: the paper's Kalman filter (section 3.1) run block by block on the measured displacement.

Consumes ``/rotor/displacement``, ``/rotor/speed``, ``/rotor/excitation``; publishes
``/bearing_id/bearing_displacement`` (DisplacementBlock, x and y at each bearing node, same sequence and stamp as the
input block) and ``/bearing_id/innovation`` (DisplacementBlock, probe channels, innovations in m), and /diagnostics.
The filter, its model cache and the health checks are :class:`bearing_id.nodes.kf_estimator_core.EstimatorCore`.
"""
from __future__ import annotations

from collections import deque
import math
import sys
import time

from diagnostic_msgs.msg import DiagnosticArray
import numpy as np
from rclpy.node import Node

from .declare import declare_parameters
from .diagnostics import diagnostics_msg, flag_best_effort, flag_publishers
from .kf_estimator_core import block_speed, EstimatorCore, NAME, SPECS
from .machine import label, machine_id
from .monitor import StreamMonitor
from .process import run_node
from .qos import qos_input, qos_stream, subscribe_latched
from .runs import excitation_of, MALFORMED, RunResolver
from .status import DiagItem, ERROR, OK, STALE, Throttle, WARN, WARN_EVERY
from .topics import (relative, TOPIC_BEARING_DISPLACEMENT, TOPIC_COEFFICIENTS, TOPIC_DISPLACEMENT, TOPIC_EXCITATION,
                     TOPIC_INNOVATION, TOPIC_SPEED)
from ..config.params import load_rig
from ..conventions import rpm_to_rad_s
from ..io import messages as M


class KFEstimator(Node):
    """The kf_estimator node: measured blocks -> bearing-node estimates and innovations, health diagnostics."""

    def __init__(self):
        super().__init__(NAME)
        self._warn_gate = Throttle(WARN_EVERY)      # one problem line per WARN_EVERY s (the latest on /diagnostics)
        self._model_gate = Throttle(60.0)           # the bearing model in use: one line a minute at most
        v = declare_parameters(self, SPECS)
        self.values = v
        rig = load_rig(v['rig_params'] or None)
        self.rig = rig
        self.machine = machine_id(v['machine_id'], self.get_namespace())
        channels = v['channels'] or [p.name for p in rig.probes]
        # blocks waiting for a model are drained when the builder thread has it (a task handed to the executor
        # wakes it), not by polling: an idle node costs no CPU
        self.core = EstimatorCore(rig, v['process_noise'], v['measurement_noise'], v['speed_band'],
                                  v['max_pending_blocks'], v['nis_window'], on_ready=self._model_ready,
                                  cutoff=v['model_cutoff'])
        self.monitor = StreamMonitor(TOPIC_DISPLACEMENT, channels, v['max_displacement'])
        self.resolver = RunResolver(v['max_pending_blocks'])
        self.last_speed = None            # (speed, wall time)
        self.speed_msgs = 0
        self.last_block_speed = None
        self.problems: deque = deque(maxlen=10)
        self.skipped = {'no_speed': 0, 'no_angles': 0, 'slow': 0}
        speeds = v['prebuild_speeds_rpm']
        if speeds is None and rig.simulation is not None:
            speeds = list(rig.simulation.speeds_rpm)
        fs = rig.simulation.sample_rate if rig.simulation is not None else None
        probes = tuple(p for p in rig.probes if p.name in channels)
        if fs and len(probes) == len(channels):
            for s in speeds or []:
                self.core.request(float(rpm_to_rad_s(s)), probes, fs)
        top = max(speeds) if speeds else 3000.0
        self.core.request_threshold(float(rpm_to_rad_s(top)) * 2.0)
        self.pub_est = self.create_publisher(M.DisplacementBlock, relative(TOPIC_BEARING_DISPLACEMENT),
                                             qos_stream())
        self.pub_nu = self.create_publisher(M.DisplacementBlock, relative(TOPIC_INNOVATION), qos_stream())
        self.pub_diag = self.create_publisher(DiagnosticArray, '/diagnostics', 10)
        # excitation and speed subscriptions first: ready together with a block, they are taken first
        subscribe_latched(self, M.Excitation, relative(TOPIC_EXCITATION), self.on_excitation)
        self._coeff_seen: deque = deque(maxlen=1000)       # (stamp, speed) of results taken (each arrives twice)
        self.coeff_used = self.coeff_skipped = 0
        if v['bearing_source'] == 'identified':
            subscribe_latched(self, M.BearingCoefficients, relative(TOPIC_COEFFICIENTS), self.on_coefficients)
        self.create_subscription(M.RotorSpeed, relative(TOPIC_SPEED), self.on_speed, qos_input(self, 50))
        self.create_subscription(M.DisplacementBlock, relative(TOPIC_DISPLACEMENT), self.on_block, qos_input(self))
        self.create_timer(v['diagnostics_period'], self.diagnostics)
        noise = f"({v['measurement_noise']:g} m)^2" if v['measurement_noise'] else 'per channel from the data'
        qn = f'{v["process_noise"]:g} m^2' if v['process_noise'] else 'from the innovations'
        self.get_logger().info(f'model: {rig.name}, probes {channels}, Q {qn}, R {noise}; '
                               f'prebuilding {len(speeds or [])} models')

    def on_speed(self, msg):
        s = float(msg.speed)
        if math.isfinite(s):
            self.last_speed = (s, time.monotonic())
        self.speed_msgs += 1

    def on_coefficients(self, msg):
        """Take an identifier's result: its fully determined coefficients become the model's bearings there."""
        try:
            d = M.coefficients_from_msg(msg)
        except (ValueError, TypeError, AttributeError) as exc:
            self._problem(f'malformed BearingCoefficients rejected: {exc}')
            return
        key = (d['stamp_ns'], d['speed'])
        if key in self._coeff_seen:
            return
        self._coeff_seen.append(key)
        finite = all(np.all(np.isfinite(d[k])) for k in ('K', 'C', 'K_std', 'C_std'))
        if not (finite and np.all(d['K_determined']) and np.all(d['C_determined']) and d['speed'] > 0):
            self.coeff_skipped += 1          # not determined: the model keeps what it has there
            return
        try:
            stds = {n: (d['K_std'][i], d['C_std'][i]) for i, n in enumerate(d['nodes'])}
            self.core.set_coefficients(d['speed'], d['coeffs'], stds)
        except ValueError as exc:
            self._problem(f'BearingCoefficients not used: {exc}')
            return
        self.coeff_used += 1
        # one line a minute at most: an identifier tracking the machine sends every speed at every solve (the model
        # in use is on /diagnostics all the time)
        if self._model_gate.due(time.monotonic()) is not None:
            self.get_logger().info(f"bearing model: identified coefficients at {d['speed'] * 30 / math.pi:.0f} rpm "
                                   f'({self.core.bearings.describe()})')

    def on_excitation(self, msg):
        try:
            stamp, run = excitation_of(msg, self.core.rotor.n_nodes)
        except MALFORMED as exc:
            self._problem(f'malformed Excitation rejected: {exc}')
            return
        new, released = self.resolver.announce(stamp, run)
        if new:
            self.get_logger().info(f'excitation: run {run.id} with {len(run.excitation)} entries')
        for b, r, (speed, contiguous) in released:    # blocks that arrived before their run's announcement
            self._submit(b, r, speed, contiguous)
        if released:
            self.drain()

    def _problem(self, text):
        self.problems.append(text)
        line = self._warn_gate.line(text, time.monotonic())
        if line is not None:
            self.get_logger().warn(line)

    def on_block(self, msg):
        try:
            b = M.block_from_msg(msg)
        except MALFORMED as exc:
            self._problem(f'malformed DisplacementBlock rejected: {exc}')
            return
        chk = self.monitor.check(b.seq, b.stamp, b.sample_rate, b.channels, b.samples)
        for p in chk.problems:
            self._problem(p)
        bad = [] if not chk.usable else M.validate_block(b, self.values['max_displacement'],
                                                         self.core.rotor.n_nodes)
        for p in bad:
            self._problem(f'block seq {b.seq} rejected: {p}')
        if not chk.usable or bad:
            return
        if b.has_sample_angles:
            speed = block_speed(b.sample_angles, b.sample_rate)
        else:
            self.skipped['no_angles'] += 1
            speed = b.speed if (math.isfinite(b.speed) and b.speed > 0) else None
        if speed is None and self.last_speed and time.monotonic() - self.last_speed[1] < self.values[
                'speed_timeout']:
            speed = self.last_speed[0]
        if speed is None:
            self.skipped['no_speed'] += 1
            self._problem(f'no speed for block seq {b.seq}: the block carries none and /rotor/speed is silent; '
                          f'block skipped')
            return
        self.last_block_speed = speed
        if speed < rpm_to_rad_s(self.values['min_speed_rpm']):
            self.skipped['slow'] += 1
            return
        if not b.has_sample_angles and b.n_samples and self.skipped['no_angles'] == 1:
            self._problem(f'block seq {b.seq} carries no sample_angles: its angle is rebuilt assuming constant '
                          f'speed over the block (biased on speed ramps)')
        run = self.resolver.resolve(b, (speed, chk.contiguous))
        if run is None:               # its run's excitation has not arrived yet: the block waits for it
            return
        self._submit(b, run, speed, chk.contiguous)
        self.drain()

    def _model_ready(self):
        """Drain the blocks waiting for a model on the executor's thread (called by the model builder's thread)."""
        ex = self.executor
        if ex is not None:
            ex.create_task(self.drain)

    def _submit(self, b, run, speed, contiguous):
        err = self.core.submit(b, run, speed, contiguous)
        if err:
            self._problem(err)

    def drain(self):
        for o in self.core.drain():
            b = o.block
            stamp = b.stamp_ns                 # the input block's stamp, to the nanosecond
            ang = b.sample_angles
            self.pub_est.publish(M.block_to_msg(
                samples=o.estimates, sequence=o.seq, sample_rate=b.sample_rate, speed=b.speed, angle=b.angle,
                probes=self.core.outputs_probes, stamp=stamp, frame_id=b.frame_id, sample_angles=ang,
                run_id=o.run_id))
            self.pub_nu.publish(M.block_to_msg(
                samples=o.innovations, sequence=o.seq, sample_rate=b.sample_rate, speed=b.speed, angle=b.angle,
                probes=b.probes, stamp=stamp, frame_id=b.frame_id, sample_angles=ang, run_id=o.run_id))

    def diagnostics(self):
        disp = self.monitor.status(f'{NAME}: input {TOPIC_DISPLACEMENT}', self.values['stale_after'])
        items = [flag_best_effort(self, TOPIC_DISPLACEMENT, flag_publishers(self, TOPIC_DISPLACEMENT, disp))]
        sp_item = DiagItem(f'{NAME}: input {TOPIC_SPEED}', OK, 'receiving', {'messages': self.speed_msgs})
        if self.last_speed is None:
            sp_item.level, sp_item.message = STALE, f'no data received on {TOPIC_SPEED}'
        elif time.monotonic() - self.last_speed[1] > self.values['stale_after']:
            sp_item.level, sp_item.message = STALE, f'no data on {TOPIC_SPEED} for ' \
                                                    f'{time.monotonic() - self.last_speed[1]:.1f} s'
        items.append(sp_item)
        rs = self.resolver
        ex = DiagItem(f'{NAME}: input {TOPIC_EXCITATION}', OK, f'{len(rs)} run(s) known',
                      {'runs': len(rs), 'blocks_waiting_for_excitation': len(rs.waiting),
                       'blocks_assigned_after_waiting': rs.released,
                       'blocks_dropped_waiting_too_long': rs.dropped})
        if rs.dropped:
            ex.level, ex.message = WARN, f'{rs.dropped} block(s) dropped after waiting too long for their run'
        if len(rs) == 0:
            ex.level, ex.message = (ERROR if self.monitor.n_blocks else STALE), \
                f'no excitation received on {TOPIC_EXCITATION}: blocks cannot be filtered'
        items.append(ex)
        proc = DiagItem(f'{NAME}: processing', OK, 'ok', {
            'blocks_without_speed': self.skipped['no_speed'], 'blocks_below_min_speed': self.skipped['slow'],
            'blocks_without_sample_angles': self.skipped['no_angles'],
            'pending_blocks': self.core.pending, 'bearing_model': self.core.bearings.describe(),
            'identified_results_used': self.coeff_used, 'undetermined_results_ignored': self.coeff_skipped})
        if self.problems:
            proc.level, proc.message = WARN, self.problems[-1]
            proc.values['problems'] = ' | '.join(list(self.problems)[-5:])
            self.problems.clear()
        items += [proc, self.core.nis_status(), self.core.health_status(), self.core.motion_status(),
                  self.core.validity_status(self.last_block_speed)]
        stamp = self.get_clock().now().to_msg()
        self.pub_diag.publish(diagnostics_msg(items, stamp, label(self.machine, self.rig.name), self.machine))

    def close(self):
        self.core.close()


def main(argv=None) -> int:
    return run_node(NAME, 'Kalman-filter estimate of the bearing-node displacements from the measured probes '
                          '(Kang et al. 2020, section 3.1), block by block.', SPECS, KFEstimator, argv)


if __name__ == '__main__':  # pragma: no cover
    sys.exit(main())
