"""Bag I/O without ROS: rosbag2 bags (MCAP or sqlite3) written and read with rosbags.

The fmm_interfaces types come from the package's own .msg files (definitions.py); the
writer takes numpy arrays or raw CDR bytes (writer.py); the reader yields aligned force and
velocity batches and decoded results, and recovers what a crash or damage left (reader.py).
"""

from fmm_ros._lazy import lazy_exports

_EXPORTS = {
    'AlignedBatch': 'reader',
    'BagDamagedError': 'errors',
    'BagError': 'errors',
    'BagMessage': 'reader',
    'BagReader': 'reader',
    'BagWriter': 'writer',
    'BatchAligner': 'reader',
    'ChannelBatch': 'reader',
    'DEFAULT_BATCH_SIZE': 'writer',
    'FRF_SUMMARY': 'definitions',
    'IMPACT_RESULT': 'definitions',
    'MessageTypeError': 'errors',
    'MissingTopicError': 'errors',
    'SAMPLE_BATCH': 'definitions',
    'TopicInfo': 'reader',
    'find_definitions': 'definitions',
    'fmm_typestore': 'definitions',
    'new_message': 'definitions',
}

__all__ = sorted(_EXPORTS)
__getattr__ = lazy_exports(__name__, _EXPORTS)
