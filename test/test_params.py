"""Node parameter tables: ranges, choices and read-only are enforced at start-up and live."""

import pytest
from rclpy.exceptions import InvalidParameterValueException
from rclpy.node import Node
from rclpy.parameter import Parameter

from fmm_ros.ros.params import Param, declare_parameters

pytestmark = pytest.mark.ros

PARAMS = (
    Param('rate_factor', 1.0, 'Speed-up against the wall clock [-]', limits=(0.01, 1000.0)),
    Param('batch_size', 500, 'Samples per message [-]', limits=(1, 100_000), read_only=True),
    Param('levels_n', [450.0, 1000.0], 'Nominal peak forces [N]', limits=(1.0, 20_000.0)),
    Param('storage', 'mcap', 'Bag storage plugin', choices=('mcap', 'sqlite3')),
)


class _Configured(Node):
    def __init__(self, **kwargs):
        super().__init__('configured', **kwargs)
        self.values = declare_parameters(self, PARAMS)


def test_defaults_and_overrides_are_returned(ros_graph):
    node = ros_graph.add(_Configured, parameter_overrides=[Parameter('rate_factor', value=20.0)])
    assert node.values == {
        'rate_factor': 20.0,
        'batch_size': 500,
        'levels_n': [450.0, 1000.0],
        'storage': 'mcap',
    }
    described = node.describe_parameter('rate_factor')
    assert described.floating_point_range[0].to_value == 1000.0
    assert '[-]' in described.description


@pytest.mark.parametrize(
    ('override', 'reason'),
    [
        (Parameter('rate_factor', value=5000.0), 'out of range'),
        (Parameter('batch_size', value=0), 'out of range'),
        (Parameter('levels_n', value=[450.0, -3.0]), '[-3.0] outside'),
        (Parameter('storage', value='bag'), "'bag' is not one of mcap, sqlite3"),
    ],
)
def test_bad_start_up_values_are_refused_with_the_reason(ros_graph, override, reason):
    with pytest.raises(InvalidParameterValueException, match=reason.replace('[', r'\[')):
        ros_graph.add(_Configured, parameter_overrides=[override])


def test_bad_live_values_are_refused_and_the_old_value_kept(ros_graph):
    node = ros_graph.add(_Configured)
    results = node.set_parameters(
        [
            Parameter('storage', value='zip'),
            Parameter('rate_factor', value=-1.0),
            Parameter('batch_size', value=1000),
        ]
    )
    assert [r.successful for r in results] == [False, False, False]
    assert 'not one of' in results[0].reason and 'out of range' in results[1].reason
    assert 'read-only' in results[2].reason
    assert node.get_parameter('storage').value == 'mcap'
    assert node.set_parameters([Parameter('rate_factor', value=50.0)])[0].successful


def test_an_integer_for_a_float_parameter_is_taken_as_a_float(ros_graph):
    node = ros_graph.add(_Configured, parameter_overrides=[Parameter('rate_factor', value=20)])
    assert node.values['rate_factor'] == 20.0 and isinstance(node.values['rate_factor'], float)
    with pytest.raises(InvalidParameterValueException, match="'fast' is not a number"):
        ros_graph.add(_Configured, parameter_overrides=[Parameter('rate_factor', value='fast')])
    assert not node.set_parameters([Parameter('rate_factor', value=True)])[0].successful
