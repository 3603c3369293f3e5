"""A bag's metadata.yaml (rosbag2 version 9) and the ROS distribution a bag is of.

rosbag2 writes `ros_distro` and a free `custom_data` string map into metadata.yaml (and the
same text into the storage file). The recorder puts each channel's ledger into custom_data,
so a bag states its own completeness; `custom_ledger` reads it back.
"""

import functools
import importlib.metadata
import json
import os
from pathlib import Path

import yaml
from rosbags.interfaces import Qos

from fmm_ros.core.signal.stream import ChannelLedger
from fmm_ros.errors import BadInputError
from fmm_ros.io.bags.definitions import BASE_STORE

ROSBAG2_VERSION = 9  # the metadata version rosbag2 on Jazzy writes
# custom_data key of the recorder's ledger: JSON, topic -> ChannelLedger.to_dict().
LEDGER_KEY = 'fmm.ledger'
# The distributions whose PyPI wheels (ros-<distro>-rclpy) or installs this could run on.
_DISTROS = ('jazzy', 'kilted', 'rolling', 'humble')


@functools.cache
def ros_distro() -> str:
    """The ROS 2 distribution in use, as rosbag2 records it in a bag.

    $ROS_DISTRO (a sourced install), else the distro of the rclpy or ament wheels installed,
    else the one whose standard types the bags use.
    """
    if os.environ.get('ROS_DISTRO'):
        return os.environ['ROS_DISTRO']
    for distro in _DISTROS:
        for package in ('rclpy', 'ament-index-python'):
            try:
                importlib.metadata.version(f'ros-{distro}-{package}')
            except importlib.metadata.PackageNotFoundError:
                continue
            return distro
    return BASE_STORE.name.split('_')[-1].lower()


def qos_profiles(profiles: list[Qos]) -> list[dict]:
    """Offered QoS profiles as rosbag2 v9 metadata lists them."""
    return [
        {
            'history': qos.history.name.lower(),
            'depth': qos.depth,
            'reliability': qos.reliability.name.lower(),
            'durability': qos.durability.name.lower(),
            'deadline': {'sec': qos.deadline.sec, 'nsec': qos.deadline.nsec},
            'lifespan': {'sec': qos.lifespan.sec, 'nsec': qos.lifespan.nsec},
            'liveliness': qos.liveliness.name.lower(),
            'liveliness_lease_duration': {
                'sec': qos.liveliness_lease_duration.sec,
                'nsec': qos.liveliness_lease_duration.nsec,
            },
            'avoid_ros_namespace_conventions': qos.avoid_ros_namespace_conventions,
        }
        for qos in profiles
    ]


def qos_yaml(profiles: list[Qos]) -> str:
    """Offered QoS profiles as the YAML text storage files carry."""
    return yaml.safe_dump(qos_profiles(profiles), default_flow_style=False, sort_keys=False)


def bag_information(
    *,
    storage: str,
    file_name: str,
    topics: list[dict],
    start_ns: int,
    end_ns: int,
    custom_data: dict[str, str],
) -> dict:
    """The `rosbag2_bagfile_information` mapping; topics: name, type, hash, qos, count."""
    count = sum(topic['count'] for topic in topics)
    duration = max(0, end_ns - start_ns) if count else 0
    start = start_ns if count else 0
    return {
        'version': ROSBAG2_VERSION,
        'storage_identifier': storage,
        'duration': {'nanoseconds': duration},
        'starting_time': {'nanoseconds_since_epoch': start},
        'message_count': count,
        'topics_with_message_count': [
            {
                'topic_metadata': {
                    'name': topic['name'],
                    'type': topic['type'],
                    'serialization_format': 'cdr',
                    'offered_qos_profiles': qos_profiles(topic['qos']),
                    'type_description_hash': topic['hash'],
                },
                'message_count': topic['count'],
            }
            for topic in topics
        ],
        'compression_format': '',
        'compression_mode': '',
        'relative_file_paths': [file_name],
        'files': [
            {
                'path': file_name,
                'starting_time': {'nanoseconds_since_epoch': start},
                'duration': {'nanoseconds': duration},
                'message_count': count,
            }
        ],
        'custom_data': dict(custom_data),
        'ros_distro': ros_distro(),
    }


def metadata_yaml(information: dict) -> str:
    """metadata.yaml's text."""
    return yaml.safe_dump(
        {'rosbag2_bagfile_information': information}, default_flow_style=False, sort_keys=False
    )


def ledger_text(ledgers: dict[str, ChannelLedger]) -> str:
    """The custom_data value of a recorder's ledger (JSON, topic -> ledger)."""
    return json.dumps({topic: ledger.to_dict() for topic, ledger in ledgers.items()})


def custom_ledger(custom_data: dict[str, str] | None) -> dict[str, ChannelLedger]:
    """The ledger a recorder wrote into custom_data (empty when there is none)."""
    text = (custom_data or {}).get(LEDGER_KEY)
    if not text:
        return {}
    try:
        data = json.loads(text)
        return {topic: ChannelLedger.from_dict(entry) for topic, entry in data.items()}
    except (ValueError, TypeError, AttributeError) as error:
        raise BadInputError(f'custom_data {LEDGER_KEY} is not a ledger: {error}') from None


def load_yaml(text: str) -> object:
    """yaml.safe_load's document, parsed by libyaml where PyYAML has it (CSafeLoader).

    The same objects (the safe constructor and resolver are shared), ten times faster: a
    replay read metadata.yaml twice, and the pure-Python parser cost it ~30 ms each time.
    """
    return yaml.load(text, Loader=getattr(yaml, 'CSafeLoader', yaml.SafeLoader))


def read_information(bag: Path) -> dict:
    """A bag directory's `rosbag2_bagfile_information` (empty without a readable metadata.yaml)."""
    path = Path(bag) / 'metadata.yaml'
    if not path.is_file():
        return {}
    try:
        document = load_yaml(path.read_text(encoding='utf-8'))
    except (yaml.YAMLError, UnicodeDecodeError):
        return {}
    information = (
        document.get('rosbag2_bagfile_information') if isinstance(document, dict) else None
    )
    return information if isinstance(information, dict) else {}
