"""A source we did not write: a plain rclpy publisher of a simulated session, no flow control.

Stands for a lab's DAQ driver or a bag player at `--rate N`: it publishes force and velocity
`SampleBatch` messages on /fmm/force and /fmm/velocity, paced to the wall clock at
`--rate-factor` times real time, and never listens to /fmm/stream_progress. It imports no
fmm_ros ROS code (only the message type and the physics core that simulates the session), so
what it does is what any RELIABLE publisher may do. `--history keep_all` asks the middleware
to block the writer when the readers' queues are full (back-pressure); `keep_last` (depth
`--depth`, rclpy's usual `create_publisher(..., 10)`) lets the writer overwrite what it could
not deliver.

It waits until both topics have `--subscribers` subscriptions, publishes the session once,
waits until the readers acknowledged everything (as a reliable source must before it quits:
a reader whose queue was full waits for the writer to resend), and prints one line,
`sent <n> samples per channel in <t> s (x<pace>), <k> publish calls failed, ...`.
`--repeat N` publishes it N times from one process, each a new acquisition, the next when a
line arrives on stdin (a benchmark's runs without a process start each).

    .venv/bin/python benchmarks/foreign_source.py --rate-factor 50 --batch 500
"""

import argparse
import array
import os
import random
import sys
import time
from pathlib import Path

import numpy as np
import rclpy
from rclpy.context import Context
from rclpy.duration import Duration
from rclpy.node import Node
from rclpy.qos import DurabilityPolicy, HistoryPolicy, QoSProfile, ReliabilityPolicy

from fmm_interfaces.msg import SampleBatch


def publisher_qos(history: str, depth: int) -> QoSProfile:
    """RELIABLE and VOLATILE, as a DAQ driver would publish; history as asked."""
    return QoSProfile(
        history=HistoryPolicy.KEEP_ALL if history == 'keep_all' else HistoryPolicy.KEEP_LAST,
        depth=depth,
        reliability=ReliabilityPolicy.RELIABLE,
        durability=DurabilityPolicy.VOLATILE,
    )


def batch_message(
    quantity: str, unit: str, samples, first: int, rate_hz: float, origin_ns: int, frame: str
) -> SampleBatch:
    """One SampleBatch, stamped at the acquisition time of its first sample."""
    msg = SampleBatch()
    stamp_ns = origin_ns + int(round(first * 1e9 / rate_hz))
    msg.header.stamp.sec, msg.header.stamp.nanosec = divmod(stamp_ns, 1_000_000_000)
    msg.header.frame_id = frame
    msg.quantity, msg.unit = quantity, unit
    msg.sample_rate_hz = rate_hz
    msg.first_sample_index = first
    msg.samples = array.array('d', samples.tobytes())
    return msg


def damage(force_n, velocity_m_s, rate_hz: float) -> None:
    """Damage the session's samples in place, as --damage says."""
    at = int(2.1 * rate_hz)  # inside the first hit's record
    force_n[at : at + 5] = float('nan')
    quiet = int(7.0 * rate_hz)  # between the first record and the second hit
    force_n[quiet : quiet + 20] = float('nan')
    velocity_m_s[quiet + 1000] = float('inf')
    force_n[quiet + 5000 : quiet + 5500] = force_n[quiet + 4999]


def publish_session(
    publishers: list, channels: tuple, rate: float, frame: str, args: argparse.Namespace
) -> str:
    """Publish the session once from index 0 at the asked pace; the line that says so."""
    failed = 0
    origin_ns = time.time_ns()
    total = channels[0][2].size
    period_s = args.batch / (rate * args.rate_factor)
    start = time.monotonic()
    first = 0
    k = 0
    jump_at = int(round(args.jump_at_s * rate))
    while first < total:
        wait = start + k * period_s - time.monotonic()
        if wait > 0:
            time.sleep(wait)
        for publisher, (quantity, unit, data) in zip(publishers, channels, strict=True):
            msg = batch_message(
                quantity,
                unit,
                data[first : first + args.batch],
                first + (args.jump_samples if first >= jump_at else 0),
                rate,
                origin_ns,
                frame,
            )
            try:
                publisher.publish(msg)
            except Exception:  # a KEEP_ALL writer whose readers stayed full: it failed
                failed += 1
        first += args.batch
        k += 1
    elapsed = time.monotonic() - start
    # A reliable writer resends until every reader acknowledged: quitting before loses
    # the tail (a reader whose queue was full has refused it and waits for the resend).
    unacked = sum(
        not p.wait_for_all_acked(Duration(seconds=args.ack_timeout_s)) for p in publishers
    )
    time.sleep(args.linger_s)
    pace = total / rate / elapsed if elapsed > 0 else float('inf')
    return (
        f'sent {total} samples per channel in {elapsed:.3f} s (x{pace:.1f}), '
        f'{failed} publish calls failed, {unacked} writers not acknowledged'
    )


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument('--rate-factor', type=float, default=50.0)
    parser.add_argument('--batch', type=int, default=500)
    parser.add_argument('--hits-per-level', type=int, default=1)
    parser.add_argument('--spacing-s', type=float, default=8.0)
    parser.add_argument('--seed', type=int, default=3)
    parser.add_argument('--quiet-zero', action='store_true', help='noise-free (exact zeros)')
    parser.add_argument('--history', choices=('keep_all', 'keep_last'), default='keep_last')
    parser.add_argument('--depth', type=int, default=10)
    parser.add_argument('--frame-id', default='lab_daq')
    parser.add_argument('--node-name', default='foreign_daq')
    parser.add_argument(
        '--damage',
        action='store_true',
        help='NaN inside the first record (2 s after its hit) and, between records (7 s '
        'into the first 8 s slot), NaN, an infinite sample and a 500-sample stuck run',
    )
    parser.add_argument(
        '--samples',
        type=Path,
        help='an .npz (force_n, velocity_m_s, sample_rate_hz) to publish instead of simulating '
        'the session here (the simulator takes seconds to import on a busy machine)',
    )
    parser.add_argument(
        '--jump-samples',
        type=int,
        default=0,
        help='from --jump-at-s on, the index runs this many samples ahead (samples skipped)',
    )
    parser.add_argument('--jump-at-s', type=float, default=2.5)
    parser.add_argument(
        '--repeat',
        type=int,
        default=1,
        help='publish the session this many times, each a new acquisition (frame_id '
        '<frame-id>_<k>, index from 0), the next when a line arrives on stdin',
    )
    parser.add_argument('--namespace', default='/fmm')
    parser.add_argument('--subscribers', type=int, default=1)
    parser.add_argument('--linger-s', type=float, default=1.0)
    parser.add_argument('--ack-timeout-s', type=float, default=60.0)
    parser.add_argument('--discovery-timeout-s', type=float, default=60.0)
    parser.add_argument(
        '--quick', action='store_true', help='publish at x100 to nobody and stop (a smoke run)'
    )
    args = parser.parse_args(argv)
    domain_id = None
    if args.quick:  # on a private domain of this host: nobody else's graph hears it
        from fmm_ros.ros.graph import private_domain_ids

        args.subscribers, args.linger_s, args.rate_factor = 0, 0.0, 100.0
        os.environ['ROS_AUTOMATIC_DISCOVERY_RANGE'] = 'LOCALHOST'
        domain_id = random.choice(private_domain_ids())

    if args.samples:
        with np.load(args.samples) as saved:
            force_n, velocity_m_s = saved['force_n'].copy(), saved['velocity_m_s'].copy()
            rate = float(saved['sample_rate_hz'])
    else:
        from fmm_ros.sim.session import simulated_session

        noise = {'force_noise_std_n': 0.0, 'velocity_noise_std_m_s': 0.0}
        session = simulated_session(
            args.hits_per_level,
            spacing_s=args.spacing_s,
            seed=args.seed,
            **(noise if args.quiet_zero else {}),
        )
        force_n, velocity_m_s, rate = session.force_n, session.velocity_m_s, session.sample_rate_hz
    if args.damage:
        damage(force_n, velocity_m_s, rate)
    channels = (('force', 'N', force_n), ('velocity', 'm/s', velocity_m_s))
    context = Context()
    rclpy.init(context=context, domain_id=domain_id)
    node = Node(args.node_name, context=context)
    qos = publisher_qos(args.history, args.depth)
    ns = args.namespace.rstrip('/')
    publishers = [node.create_publisher(SampleBatch, f'{ns}/{q}', qos) for q, _, _ in channels]
    try:
        deadline = time.monotonic() + args.discovery_timeout_s
        while any(p.get_subscription_count() < args.subscribers for p in publishers):
            if time.monotonic() > deadline:
                print('no subscriber matched', file=sys.stderr)
                return 2
            time.sleep(0.01)
        time.sleep(0.5)  # both topics matched on the readers' side too
        for run in range(args.repeat):
            if run and not sys.stdin.readline():  # the next acquisition when told; EOF: done
                break
            frame = args.frame_id if args.repeat == 1 else f'{args.frame_id}_{run}'
            print(publish_session(publishers, channels, rate, frame, args), flush=True)
    finally:
        node.destroy_node()
        context.try_shutdown()
    return 0


if __name__ == '__main__':
    sys.exit(main())
