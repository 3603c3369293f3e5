"""Every named constant fmm_ros's layers share, each in one place.

The paper's numbers, the acquisition's, the channels and their units, topic and service names,
analysis bands. Imports nothing, so the ROS-free core, the file I/O, the simulators and the ROS
shell can all take their constants from here. A value a single module owns (a fit's tolerance,
a node's queue depth) stays in that module; what two places must agree on lives here.
"""

from dataclasses import dataclass
from typing import NamedTuple


class Channel(NamedTuple):
    """A sample channel: `SampleBatch.quantity` and `SampleBatch.unit` (SI)."""

    quantity: str
    unit: str


FORCE = Channel('force', 'N')
"""The impact hammer's force channel."""
VELOCITY = Channel('velocity', 'm/s')
"""The laser vibrometer's velocity channel."""
CHANNELS: tuple[Channel, ...] = (FORCE, VELOCITY)
ACCELERATION = Channel('acceleration', 'm/s^2')
"""An accelerometer's channel: published on the response (velocity) topic in its place."""
DISPLACEMENT = Channel('displacement', 'm')
"""A displacement sensor's channel, likewise."""
RESPONSE_CHANNELS: tuple[Channel, ...] = (VELOCITY, ACCELERATION, DISPLACEMENT)
"""What the response topic may carry; a SampleBatch's quantity says which."""


class TopicQos(NamedTuple):
    """A topic's QoS in ROS-free terms.

    `fmm_ros.ros.qos` makes its rclpy profile of it, and a bag's metadata records it as the
    topic's offered profile (`io.bags.writer.bag_qos`).
    """

    keep_all: bool
    depth: int
    reliable: bool
    transient_local: bool


SAMPLE_TOPIC_QOS = TopicQos(keep_all=True, depth=100, reliable=True, transient_local=False)
"""The sample topics' QoS: `fmm_ros.ros.qos.SAMPLE_QOS` (its docstring says why)."""

# -- acquisition (the paper's Sec. 4) -----------------------------------------------------------
SAMPLE_RATE_HZ = 10_000.0
"""Sampling rate of both channels in the paper, and every source's default [Hz]."""
BATCH_SIZE = 500
"""Samples per channel in one SampleBatch message [samples]: every source's default (the
simulated hammer, the DAQ, `fmm import`, the bag writer and the demo's smallest batch); at
10 kHz 20 messages a second a channel, which keeps rclpy's per-message cost small."""
RECORD_DURATION_S = 33.0
"""Length of one impact record in the paper (frequency resolution 1/33 Hz) [s]."""

# -- the paper's friction contact and hammer levels -------------------------------------------


@dataclass(frozen=True)
class PaperLevel:
    """One of the paper's nominal hammer levels: its peak force and the mean impulse measured."""

    name: str
    peak_force_n: float
    impulse_n_s: float


PAPER_LEVELS: tuple[PaperLevel, ...] = (
    PaperLevel('low', 450.0, 0.98),
    PaperLevel('medium', 1000.0, 1.42),
    PaperLevel('high', 1450.0, 1.64),
)
"""The paper's three levels (Secs. 4-5), in ascending force."""
LEVEL_TOLERANCE_N = 50.0
"""A hit counts at a level when its peak is within this of the nominal peak (the paper) [N]."""
PAPER_MU = 0.113
"""Best-fit Coulomb friction coefficient of the paper's PTFE pin on lubricated steel [-]."""

# -- analysis bands and windows -----------------------------------------------------------------
MISFIT_BAND_LIMIT_HZ = 20.0
"""Top of the mobility band a fit's FRF misfit and the diagnosis's FRF gap use [Hz]: the FMM's
mode (2.2 Hz) and the odd harmonics friction puts into its response."""
SETTLE_S = 1.0
"""A motion window runs this long past the model's rest: what residuals are judged over [s]."""
MU_DRIFT = 'mu_drift'
"""The effect 'mu changes from hit to hit, trending in hit order' (wear, run-in, temperature):
what the diagnosis names and the proof data (`fmm_ros.sim.hidden_effects`) hide by this name."""

# -- ROS names (also the topics of bags, which are read and written without ROS) ----------------
# Relative, so a node resolves them in its namespace: `fmm/force` is /fmm/force in the root
# namespace and /rig2/fmm/force under `--ros-args -r __ns:=/rig2`, and two rigs share one graph
# without cross-talk. Bags hold the resolved names; readers find a channel by its name's tail.
FORCE_TOPIC = 'fmm/force'
VELOCITY_TOPIC = 'fmm/velocity'
LIVE_TOPICS = {FORCE.quantity: 'fmm/live/force', VELOCITY.quantity: 'fmm/live/velocity'}
"""Each channel decimated for live plots (DisplayPoint, one point per message), by quantity:
what Foxglove, PlotJuggler and the station page plot (the live node publishes them)."""
CLOCK_TOPIC = '/clock'
"""Signal time (rosgraph_msgs/Clock), published by the source: the one time base of the
graph's stamps, absolute as ROS sim time has it (`fmm_ros.ros.timebase`)."""
APPLIED_FORCE_TOPIC = 'fmm/sim/applied_force'
"""Simulation only: the force the hammer applies (noise-free), which drives rig_sim."""
IMPACTS_TOPIC = 'fmm/impacts'
FRF_TOPIC = 'fmm/frf'
FRICTION_TOPIC = 'fmm/friction'
"""The fitter's running mu (FrictionEstimate), one message after every accepted impact."""
STREAM_PROGRESS_TOPIC = 'fmm/stream_progress'
"""Where consumers of sample batches say how far they have got (flow control of the sources)."""
DIAGNOSTICS_TOPIC = '/diagnostics'
"""Health of every node (diagnostic_msgs/DiagnosticArray): absolute, as the ROS convention
has it (rqt_robot_monitor and Foxglove read it); statuses carry the node's full name."""
DECISIONS_TOPIC = 'fmm/impact_decisions'
"""Decisions about hits (ImpactDecision) overruling the flags: the operator's, a judge's."""
SESSION_INFO_TOPIC = 'fmm/session_info'
"""What the session tests and who runs it (SessionInfo), as entered at the station."""
JUDGE_SERVICE = 'fmm/judge_impact'
"""The station's service: decide about one hit (JudgeImpact)."""
FIT_SERVICE = 'fmm/fit_friction'
DIAGNOSE_SERVICE = 'fmm/diagnose_model'
RECALL_SERVICE = 'fmm/recall_samples'
"""The fitter's service: the samples its history still holds (RecallSamples), for a respawned
recorder to fill the stretch it was down."""
RECORDED_TOPICS = (
    FORCE_TOPIC,
    VELOCITY_TOPIC,
    IMPACTS_TOPIC,
    FRF_TOPIC,
    FRICTION_TOPIC,
    DIAGNOSTICS_TOPIC,
    CLOCK_TOPIC,
    DECISIONS_TOPIC,
    SESSION_INFO_TOPIC,
)
"""What the recorder (and `fmm record`) records unless told otherwise."""


def resolve_name(name: str, namespace: str = '/') -> str:
    """The full name a relative topic or service name has in namespace (absolute: itself)."""
    if name.startswith('/'):
        return name
    return namespace.rstrip('/') + '/' + name


# -- files ------------------------------------------------------------------------------------
BAG_STORAGES = ('mcap', 'sqlite3')
"""The rosbag2 storage formats bags are written in (`fmm record --storage`, the recorder)."""
FRF_FORMATS = ('csv', 'uff', 'json')
"""The FRF exchange formats `fmm export` writes (`fmm_ros.io.frf_files`)."""

# -- how results are shown to people: CLI text and report pages alike -------------------------
MM_PER_M = 1e3
"""Receptance is shown in mm/N and mobility in mm/(N*s), so numbers stay short (JSON, bags
and messages stay in SI)."""
RECEPTANCE_DISPLAY_UNIT = 'mm/N'
MOBILITY_DISPLAY_UNIT = 'mm/(N·s)'
REPORT_DPI = 110.0
"""Resolution of report figures [dots per inch]: a 7.5 in figure is 825 px, the page's column."""
