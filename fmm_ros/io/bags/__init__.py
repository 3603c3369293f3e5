"""Bag I/O without ROS: rosbag2 bags (MCAP or sqlite3) written and read with rosbags.

The fmm_interfaces types come from the package's own .msg files (definitions.py); the
writer takes numpy arrays or raw CDR bytes (writer.py); the reader yields aligned force and
velocity batches and decoded results, and recovers what a crash or damage left (reader.py).
"""

from fmm_ros.io.bags.definitions import (
    FRF_SUMMARY,
    IMPACT_RESULT,
    SAMPLE_BATCH,
    find_definitions,
    fmm_typestore,
    new_message,
)
from fmm_ros.io.bags.errors import BagDamagedError, BagError, MessageTypeError, MissingTopicError
from fmm_ros.io.bags.reader import (
    AlignedBatch,
    BagMessage,
    BagReader,
    BatchAligner,
    ChannelBatch,
    TopicInfo,
)
from fmm_ros.io.bags.writer import (
    DEFAULT_BATCH_SIZE,
    BagWriter,
)

__all__ = [
    'AlignedBatch',
    'BagDamagedError',
    'BagError',
    'BagMessage',
    'BagReader',
    'BagWriter',
    'BatchAligner',
    'ChannelBatch',
    'DEFAULT_BATCH_SIZE',
    'FRF_SUMMARY',
    'IMPACT_RESULT',
    'MissingTopicError',
    'SAMPLE_BATCH',
    'TopicInfo',
    'MessageTypeError',
    'find_definitions',
    'fmm_typestore',
    'new_message',
]
