"""The fmm_interfaces message types for rosbags, read from the package's own .msg files.

One source of truth: the typestore is built from `fmm_interfaces/msg/*.msg` wherever this
installation keeps them, never from a copy in Python. Where that is, in lookup order:

1. a source checkout (or editable install): `fmm_interfaces/msg` beside the `fmm_ros` package;
2. a ROS workspace: `<prefix>/share/fmm_interfaces/msg` for each prefix in AMENT_PREFIX_PATH
   that the ament index lists fmm_interfaces under (what ament_index_python does);
3. a plain pip install: `fmm_ros/interface_definitions/msg`, which setup.py copies from
   `fmm_interfaces/msg` when it builds the package (generated, never committed).
"""

import functools
import os
from collections.abc import Callable, Mapping
from dataclasses import dataclass
from importlib import resources
from pathlib import Path

import numpy as np
from rosbags.interfaces import Nodetype
from rosbags.typesys import Stores, get_types_from_msg, get_typestore
from rosbags.typesys.store import Typestore

from fmm_ros.errors import BadInputError

INTERFACES_PACKAGE = 'fmm_interfaces'
SAMPLE_BATCH = 'fmm_interfaces/msg/SampleBatch'
IMPACT_RESULT = 'fmm_interfaces/msg/ImpactResult'
FRF_SUMMARY = 'fmm_interfaces/msg/FrfSummary'
IMPACT_DECISION = 'fmm_interfaces/msg/ImpactDecision'
SESSION_INFO = 'fmm_interfaces/msg/SessionInfo'

# The ROS 2 distribution whose standard types (std_msgs, builtin_interfaces, ...) bags use.
BASE_STORE = Stores.ROS2_JAZZY

# Name of the package-data folder setup.py fills at build time (see setup.py, build_py).
PACKAGE_DATA_DIR = 'interface_definitions'


@dataclass(frozen=True)
class InterfaceDefinitions:
    """The .msg texts of fmm_interfaces, by full type name, and where they were found."""

    texts: Mapping[str, str]
    origin: str


def _read_msg_dir(msg_dir, origin: str) -> InterfaceDefinitions | None:
    """Every *.msg in msg_dir (a Path or importlib Traversable), or None when there is none."""
    if not msg_dir.is_dir():
        return None
    texts = {
        f'{INTERFACES_PACKAGE}/msg/{entry.name[:-4]}': entry.read_text(encoding='utf-8')
        for entry in msg_dir.iterdir()
        if entry.name.endswith('.msg')
    }
    return InterfaceDefinitions(dict(sorted(texts.items())), origin) if texts else None


def from_checkout() -> InterfaceDefinitions | None:
    """Definitions of a source checkout: fmm_interfaces/msg next to the fmm_ros package."""
    repo = Path(__file__).resolve().parents[3]
    return _read_msg_dir(repo / INTERFACES_PACKAGE / 'msg', f'checkout {repo}')


def from_ament_prefixes(ament_prefix_path: str | None = None) -> InterfaceDefinitions | None:
    """Definitions installed in a ROS workspace, found through the ament index.

    ament_prefix_path defaults to the AMENT_PREFIX_PATH environment variable.
    """
    if ament_prefix_path is None:
        ament_prefix_path = os.environ.get('AMENT_PREFIX_PATH', '')
    for prefix in filter(None, ament_prefix_path.split(os.pathsep)):
        share = Path(prefix) / 'share'
        marker = share / 'ament_index' / 'resource_index' / 'packages' / INTERFACES_PACKAGE
        if marker.is_file():
            found = _read_msg_dir(share / INTERFACES_PACKAGE / 'msg', f'ament prefix {prefix}')
            if found:
                return found
    return None


def from_package_data() -> InterfaceDefinitions | None:
    """Definitions setup.py copied into the built fmm_ros package (a pip install)."""
    folder = resources.files('fmm_ros') / PACKAGE_DATA_DIR / 'msg'
    return _read_msg_dir(folder, f'package data {folder}')


LOCATORS: tuple[Callable[[], InterfaceDefinitions | None], ...] = (
    from_checkout,
    from_ament_prefixes,
    from_package_data,
)


def find_definitions() -> InterfaceDefinitions:
    """The fmm_interfaces .msg texts of this installation (first locator that finds them)."""
    for locate in LOCATORS:
        found = locate()
        if found:
            return found
    raise FileNotFoundError(
        'cannot find the fmm_interfaces .msg files: not beside the fmm_ros package '
        '(source checkout), not in any AMENT_PREFIX_PATH prefix (ROS workspace: source its '
        'setup script), and not in the fmm_ros package data (reinstall fmm_ros with pip)'
    )


def types_from_definitions(definitions: InterfaceDefinitions) -> dict:
    """The rosbags field definitions of every message in definitions."""
    types: dict = {}
    for name, text in definitions.texts.items():
        types.update(get_types_from_msg(text, name))
    return types


def new_typestore(types: dict | None = None) -> Typestore:
    """A fresh Jazzy typestore with types (default: fmm_interfaces) registered."""
    store = get_typestore(BASE_STORE)
    store.register(types_from_definitions(find_definitions()) if types is None else types)
    return store


@functools.cache
def fmm_typestore() -> Typestore:
    """The shared Jazzy typestore with the fmm_interfaces types: do not register more in it."""
    return new_typestore()


def new_message(store: Typestore, msgtype: str, **fields):
    """A message of msgtype with fields set and every other field zero, empty or default.

    Saves writing out all 20-odd fields of an ImpactResult; an unknown field name is an
    error, so a typo does not silently leave a field at zero.
    """
    try:
        cls = store.types[msgtype]
        _, field_defs = store.fielddefs[msgtype]
    except KeyError:
        raise BadInputError(f'unknown message type {msgtype!r}') from None
    names = [name for name, _ in field_defs]
    if unknown := sorted(set(fields) - set(names)):
        raise BadInputError(
            f'{msgtype} has no field {", ".join(unknown)} (fields: {", ".join(names)})'
        )
    values = {
        name: fields[name] if name in fields else _default(store, desc) for name, desc in field_defs
    }
    return cls(**values)


def _default(store: Typestore, desc) -> object:
    """The zero value of one rosbags field description."""
    kind, detail = desc
    if kind == Nodetype.BASE:
        base = detail[0]
        if base in ('string', 'bounded_string'):
            return ''
        return False if base == 'bool' else (0.0 if base.startswith('float') else 0)
    if kind == Nodetype.NAME:
        return new_message(store, detail)
    if kind in (Nodetype.ARRAY, Nodetype.SEQUENCE):
        element, size = detail
        count = size if kind == Nodetype.ARRAY else 0
        if element[0] == Nodetype.BASE and element[1][0] not in ('string', 'bounded_string'):
            dtype = {'bool': np.bool_, 'byte': np.uint8, 'char': np.uint8}.get(
                element[1][0], np.dtype(element[1][0])
            )
            return np.zeros(count, dtype=dtype)
        return [_default(store, element) for _ in range(count)]
    raise BadInputError(f'unsupported field kind {kind!r}')
