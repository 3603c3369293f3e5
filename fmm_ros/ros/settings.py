"""The parameters several nodes (and the `fmm` commands that start them) share, declared once.

Standard library only (with the package's constants), so `fmm --help` can show them without
rclpy; `fmm_ros.ros.common.shared_params` makes a node's parameters of them.
"""

from dataclasses import dataclass

from fmm_ros.constants import BAG_STORAGES, BATCH_SIZE, PAPER_LEVELS, SAMPLE_RATE_HZ
from fmm_ros.core.settings import setting
from fmm_ros.core.signal.judging import MODES


@dataclass(frozen=True)
class NodeSettings:
    """The parameters several nodes take, each declared once (`shared_params`).

    The `fmm` commands that start nodes (the demo) take their options from here too. A node
    that takes one states only its own default where its role asks for another (the
    hammer's frame_id, the station's port) and whether it can be set live.
    """

    rate_factor: float = setting(
        1.0,
        unit='-',
        help="Speed against real time (a player's: against the recorded pace); 1 is real time",
        limits=(0.01, 1000.0),
    )
    sample_rate_hz: float = setting(
        SAMPLE_RATE_HZ,
        unit='Hz',
        help="Sample rate of a source's channels (a device's sample clock)",
        limits=(100.0, 1e7),
    )
    batch_size: int = setting(
        BATCH_SIZE,
        unit='-',
        help='Samples per channel per published message (>= 500 keeps rclpy cheap)',
        limits=(1, 1_000_000),
    )
    seed: int = setting(
        0, unit='-', help="Seed of the node's random draws (session, noise)", limits=(0, 2**31 - 1)
    )
    frame_id: str = setting(
        'fmm', help='Frame id in the header of what the node publishes (a sensor: its name)'
    )
    host: str = setting(
        '127.0.0.1',
        help='Address the server binds (127.0.0.1: this PC only; 0.0.0.0: the lab network)',
    )
    port: int = setting(
        8080, unit='-', help='TCP port of the server (0: any free port)', limits=(0, 65535)
    )
    level_names: tuple[str, ...] = setting(
        tuple(level.name for level in PAPER_LEVELS),
        help='Names of the nominal force levels, in order (the analyzer: [""] to cluster peak '
        'forces instead)',
    )
    level_peak_forces_n: tuple[float, ...] = setting(
        tuple(level.peak_force_n for level in PAPER_LEVELS),
        unit='N',
        help='Nominal peak force per level',
        limits=(1.0, 1e6),
    )
    hits_per_level: int = setting(
        10, unit='-', help='Hits at each level of a simulated session', limits=(1, 10_000)
    )
    storage: str = setting(
        'mcap', help='Storage plugin (rosbag2) of a bag written', choices=BAG_STORAGES
    )
    history_s: float = setting(
        60.0,
        unit='s',
        help='Stream history kept to cut hits from (>= the analyzer window + latency)',
        limits=(1.0, 3600.0),
    )
    recorder_bag: str = setting(
        '',
        help="The recorder's bag_path, read for what this node's stream never got (it was "
        'down): that bag, or a <bag_path>_<n> beside it; "" for none',
    )


@dataclass(frozen=True)
class StationSettings:
    """How the station judges a new hit: the station node's parameters and `fmm station`'s."""

    judge_mode: str = setting(
        'flags',
        help='Who judges a new hit: flags (the analyzer), manual (the operator: held pending '
        'until decided) or function (judge_function)',
        choices=MODES,
    )
    judge_function: str = setting(
        '',
        help='Module:function called with (ImpactRecord, ImpactResult) in function mode; '
        'returns a bool or (bool, reason)',
    )
