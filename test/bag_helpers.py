"""Helpers shared by the bag tests: messages with every field set, field-by-field equality."""

import numpy as np

from fmm_ros.io.bags import new_message


def random_message(store, msgtype: str, rng: np.random.Generator):
    """A message with every field set to a non-default random value."""
    _, fields = store.fielddefs[msgtype]
    values = {}
    for name, (kind, detail) in fields:
        if name == 'header':
            values[name] = new_message(
                store,
                'std_msgs/msg/Header',
                frame_id=f'frame{rng.integers(9)}',
                stamp=new_message(
                    store,
                    'builtin_interfaces/msg/Time',
                    sec=int(rng.integers(1, 2**31 - 1)),
                    nanosec=int(rng.integers(0, 10**9)),
                ),
            )
            continue
        base = detail[0] if kind == 1 else detail[0][1][0]
        count = None if kind == 1 else int(rng.integers(1, 40))
        if base == 'string':
            value = [f's{rng.integers(1000)}' for _ in range(count or 1)]
        elif base == 'bool':
            value = [bool(rng.integers(2)) for _ in range(count or 1)]
        elif base.startswith('float'):
            value = rng.normal(size=count or 1)
        else:
            value = rng.integers(0, 2**31, size=count or 1).astype(np.dtype(base))
        if count is None:
            value = value[0].item() if isinstance(value, np.ndarray) else value[0]
        values[name] = value
    return new_message(store, msgtype, **values)


def assert_same(decoded, expected, path: str = 'msg') -> None:
    """Field-by-field equality of an mcap_ros2 or rosbags message with a rosbags message."""
    for name in (n for n in dir(expected) if not n.startswith('_')):
        want = getattr(expected, name)
        got = getattr(decoded, name)
        if hasattr(want, '__msgtype__'):
            assert_same(got, want, f'{path}.{name}')
        elif isinstance(want, np.ndarray):
            np.testing.assert_array_equal(np.asarray(got), want, err_msg=f'{path}.{name}')
        else:
            assert list(got) == list(want) if isinstance(want, list) else got == want, (
                f'{path}.{name}: {got!r} != {want!r}'
            )
