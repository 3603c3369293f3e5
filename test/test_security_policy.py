"""The SROS2 policy (config/sros2/policy.xml) allows what each node really does, and is well formed.

Every node of the package is started in a graph and asked what it created (publishers,
subscriptions, services, clients, as the ROS graph sees them); each must be allowed by its
enclave's profile, names resolved as SROS2 resolves them (relative to the profile's
namespace, ~ the node's own). The policy's structure is checked against the rules of the
SROS2 policy schema 0.2.0 (sros2 is not on PyPI: `ros2 security generate_artifacts`
validates it against the schema itself on a lab install). And the venv's middleware is shown
to refuse a secured node, as docs/howto/security.md says.
"""

import fnmatch
import os
import subprocess
import sys
import xml.etree.ElementTree as ElementTree
from pathlib import Path

import numpy as np
import pytest

from fmm_ros.ros.graph import private_domain_id
from fmm_ros.ros.nodes import NODES, node_class

POLICY = Path(__file__).resolve().parents[1] / 'config' / 'sros2' / 'policy.xml'
# Element -> (allowed children, attributes: name -> allowed values or None for any text).
SCHEMA = {
    'policy': ({'enclaves'}, {'version': {'0.2.0'}}),
    'enclaves': ({'enclave'}, {}),
    'enclave': ({'profiles'}, {'path': None}),
    'profiles': ({'profile', 'metadata'}, {'type': None}),
    'profile': ({'topics', 'services', 'actions'}, {'ns': None, 'node': None}),
    'topics': ({'topic'}, {'publish': {'ALLOW', 'DENY'}, 'subscribe': {'ALLOW', 'DENY'}}),
    'services': ({'service'}, {'reply': {'ALLOW', 'DENY'}, 'request': {'ALLOW', 'DENY'}}),
    'actions': ({'action'}, {'call': {'ALLOW', 'DENY'}, 'execute': {'ALLOW', 'DENY'}}),
}
REQUIRED = {'policy': {'version'}, 'enclave': {'path'}, 'profile': {'ns', 'node'}}
NO_ATTRIBUTES: set[str] = set()
# Which attribute of a list element grants which kind of entity.
GRANTS = {'publish': 'publish', 'subscribe': 'subscribe', 'reply': 'reply', 'request': 'request'}


def check_element(element):
    """The element and its children against SCHEMA; the problems found."""
    problems = []
    children, attributes = SCHEMA.get(element.tag, (None, None))
    if children is None:
        return [f'unknown element <{element.tag}>']
    for name, value in element.attrib.items():
        if name not in attributes:
            problems.append(f'<{element.tag}> has no attribute {name}')
        elif attributes[name] is not None and value not in attributes[name]:
            problems.append(f'<{element.tag} {name}="{value}"> is not one of {attributes[name]}')
    problems += [
        f'<{element.tag}> lacks {name}'
        for name in REQUIRED.get(element.tag, NO_ATTRIBUTES) - set(element.attrib)
    ]
    for child in element:
        if child.tag in ('topic', 'service', 'action'):
            if element.tag != f'{child.tag}s' or not (child.text or '').strip():
                problems.append(f'<{child.tag}> misplaced or empty in <{element.tag}>')
        elif child.tag not in children:
            problems.append(f'<{child.tag}> is not allowed in <{element.tag}>')
        else:
            problems += check_element(child)
    if element.tag in ('enclaves', 'enclave', 'profiles') and not len(element):
        problems.append(f'<{element.tag}> is empty')
    return problems


def enclaves():
    """{enclave path: [profile element, ...]}."""
    root = ElementTree.parse(POLICY).getroot()
    return {
        enclave.get('path'): list(enclave.iter('profile'))
        for enclave in root.find('enclaves').findall('enclave')
    }


def resolve(name, namespace, node):
    """A policy name as SROS2 expands it for a profile."""
    base = namespace.rstrip('/')
    if name.startswith('~'):
        return f'{base}/{node}{name[1:]}'
    return name if name.startswith('/') else f'{base}/{name}'


def allowed(profile):
    """{'publish'|'subscribe'|'reply'|'request': [resolved name patterns]} of a profile."""
    grants = {kind: [] for kind in GRANTS}
    for element in profile:
        for attribute, kind in GRANTS.items():
            if element.get(attribute) == 'ALLOW':
                grants[kind] += [
                    resolve(item.text.strip(), profile.get('ns'), profile.get('node'))
                    for item in element
                ]
    return grants


def created(node):
    """{'publish'|...: names} a running node created, as the graph reports them."""
    name, namespace = node.get_name(), node.get_namespace()
    return {
        'publish': {t for t, _ in node.get_publisher_names_and_types_by_node(name, namespace)},
        'subscribe': {t for t, _ in node.get_subscriber_names_and_types_by_node(name, namespace)},
        'reply': {s for s, _ in node.get_service_names_and_types_by_node(name, namespace)},
        'request': {c for c, _ in node.get_client_names_and_types_by_node(name, namespace)},
    }


def uncovered(node, profile):
    """What the node created that the profile does not allow."""
    grants = allowed(profile)
    return sorted(
        (kind, name)
        for kind, names in created(node).items()
        for name in names
        if not any(fnmatch.fnmatchcase(name, pattern) for pattern in grants[kind])
    )


def test_the_policy_follows_the_sros2_schema_rules():
    root = ElementTree.parse(POLICY).getroot()
    assert root.tag == 'policy'
    assert check_element(root) == []
    found = enclaves()
    assert set(found) == {f'/fmm/{name}' for name in NODES} | {'/fmm/rig', '/fmm/operator'}
    for path, profiles in found.items():
        nodes = [profile.get('node') for profile in profiles]
        assert len(set(nodes)) == len(nodes), path


def test_the_one_process_rig_enclave_repeats_each_node_profile():
    found = enclaves()
    rig = {profile.get('node'): allowed(profile) for profile in found['/fmm/rig']}
    assert set(rig) == set(NODES) - {'player'}
    for name, grants in rig.items():
        assert grants == allowed(found[f'/fmm/{name}'][0]), name


def lab_file(folder):
    """A small CSV in the fmm layout, for the daq node's file backend."""
    from fmm_ros.core.signal.records import write_impact_csv

    path = folder / 'lab.csv'
    write_impact_csv(path, np.zeros(2000), np.zeros(2000), 10_000.0)
    return path


def small_bag(folder):
    """A bag with the package's sample topics, for the player."""
    from fmm_ros.constants import APPLIED_FORCE_TOPIC, FORCE
    from fmm_ros.io.bags.writer import BagWriter

    path = folder / 'bag'
    with BagWriter(path, time_origin_ns=10**18) as writer:
        writer.write_signals(np.zeros(1000), np.zeros(1000), 10_000.0)
        writer.write_sample_batch(
            APPLIED_FORCE_TOPIC,
            np.zeros(1000),
            quantity=(FORCE.quantity, FORCE.unit),
            sample_rate_hz=10_000.0,
            first_sample_index=0,
        )
    return path


@pytest.mark.ros
def test_every_node_creates_only_what_its_profile_allows(ros_graph, tmp_path):
    from rclpy.parameter import Parameter

    from fmm_ros.ros.demo import _Results

    overrides = {
        'daq': [
            Parameter('backend', value='file'),
            Parameter('file_path', value=str(lab_file(tmp_path))),
        ],
        'recorder': [Parameter('bag_path', value=str(tmp_path / 'recorded'))],
        'player': [Parameter('bag_path', value=str(small_bag(tmp_path)))],
    }
    nodes = {
        name: ros_graph.add(node_class(name), parameter_overrides=overrides.get(name, []))
        for name in NODES
    }
    results = ros_graph.add(_Results, on_impact=lambda _: None)
    found = enclaves()
    for name, node in nodes.items():
        assert created(node)['publish'], name  # the graph knows the node's entities
        (profile,) = found[f'/fmm/{name}']
        assert uncovered(node, profile) == [], name
    assert created(nodes['fitter'])['reply'] >= {'/fmm/fit_friction', '/fmm/diagnose_model'}
    (operator,) = found['/fmm/operator']
    assert uncovered(results, operator) == []
    assert created(results)['request'] >= {'/fmm/fit_friction', '/fmm/diagnose_model'}


@pytest.mark.ros
def test_the_venv_middleware_refuses_a_secured_node(tmp_path):
    """The PyPI Fast DDS is built without DDS security: enforced security cannot start."""
    (tmp_path / 'keystore' / 'enclaves').mkdir(parents=True)
    env = dict(
        os.environ,
        ROS_SECURITY_ENABLE='true',
        ROS_SECURITY_STRATEGY='Enforce',
        ROS_SECURITY_KEYSTORE=str(tmp_path / 'keystore'),
        ROS_SECURITY_ENCLAVE_OVERRIDE='/',
        ROS_AUTOMATIC_DISCOVERY_RANGE='LOCALHOST',
        ROS_DOMAIN_ID=str(private_domain_id()),
    )
    script = 'import rclpy; rclpy.init(); rclpy.create_node("secured")'
    run = subprocess.run(
        [sys.executable, '-c', script], env=env, capture_output=True, text=True, timeout=60
    )
    assert run.returncode != 0
    assert "doesn't have the security libraries" in run.stderr or 'SECURITY ERROR' in run.stderr
