"""The import rules ARCHITECTURE.md states, held as data.

Every `fmm_ros` module belongs to a layer (its top-level folder, the core's by stage); a layer
imports only the layers listed for it in LAYERS, at module level or inside a function alike.
No two modules import each other, even through others. The nodes are imported only above
them: by the launcher, the params-file writer, the demo and `fmm record`.
"""

import ast
from pathlib import Path

PACKAGE = Path(__file__).resolve().parents[1] / 'fmm_ros'

BASE = {'fmm_ros', 'constants', 'errors', 'units', '_lazy'}
"""What every layer may import: the version, the shared constants, the refusal family, the
unit table and the lazy package namespaces."""
CORE = {'core', 'core.physics', 'core.signal', 'core.identify', 'core.diagnose'}

LAYERS: dict[str, set[str]] = {
    'fmm_ros': set(),
    'constants': set(),
    'errors': set(),
    'units': {'errors'},
    '_lazy': set(),
    # core/settings.py and core/_checks.py: the declarations and checks every stage uses.
    'core': BASE,
    'core.physics': BASE | {'core'},
    'core.signal': BASE | {'core'},
    'core.identify': BASE | {'core', 'core.physics', 'core.signal'},
    'core.diagnose': BASE | {'core', 'core.physics', 'core.signal', 'core.identify'},
    'io': BASE | {'core', 'core.signal'},
    'sim': BASE | {'core', 'core.physics', 'io'},
    'workflows': BASE | CORE | {'io'},
    # The report draws what the workflows computed; it takes the core's result types and
    # declarations directly, and the paper's figures simulate (sim).
    'report': BASE | CORE | {'io', 'sim', 'workflows'},
    'campaign': BASE | CORE | {'io', 'workflows', 'report'},
    # The station's page (state and server), ROS-free, beneath its node in ros/.
    'station': BASE | CORE | {'io', 'workflows'},
    'ros': BASE | CORE | {'io', 'sim', 'workflows', 'report', 'station'},
    # The command is the top: it parses options into the core's settings and calls any layer.
    'cli': BASE | CORE | {'io', 'sim', 'workflows', 'report', 'campaign', 'ros'},
}

NODES_IMPORTED_BY = {
    'fmm_ros.cli.record',
    'fmm_ros.cli.station',
    'fmm_ros.ros.demo',
    'fmm_ros.ros.launch',
    'fmm_ros.ros.params_file',
}
"""The modules above the nodes that may import `fmm_ros.ros.nodes` (the nodes' own modules
import none of it)."""


def module_name(path: Path) -> str:
    parts = path.relative_to(PACKAGE.parent).with_suffix('').parts
    return '.'.join(parts[:-1] if parts[-1] == '__init__' else parts)


MODULES = {module_name(path): path for path in sorted(PACKAGE.rglob('*.py'))}


def layer(module: str) -> str:
    parts = module.split('.')
    if len(parts) == 1:
        return 'fmm_ros'
    if parts[1] == 'core' and len(parts) > 2 and f'core.{parts[2]}' in CORE:
        return f'core.{parts[2]}'
    return parts[1]


def imports(module: str) -> set[str]:
    """The fmm_ros modules module imports anywhere in its text (submodules where named)."""
    found = set()
    for node in ast.walk(ast.parse(MODULES[module].read_text(encoding='utf-8'))):
        if isinstance(node, ast.ImportFrom) and node.level == 0 and node.module:
            names = [f'{node.module}.{alias.name}' for alias in node.names]
            found.update(name if name in MODULES else node.module for name in names)
        elif isinstance(node, ast.Import):
            found.update(alias.name for alias in node.names)
    return {name for name in found if name in MODULES and name != module}


GRAPH = {module: imports(module) for module in MODULES}


def test_every_module_has_a_layer_with_rules():
    assert {layer(module) for module in MODULES} <= set(LAYERS)
    assert len(MODULES) > 100


def test_layers_import_only_what_their_rules_allow():
    upward = sorted(
        f'{module} imports {target}'
        for module, targets in GRAPH.items()
        for target in targets
        if layer(target) != layer(module) and layer(target) not in LAYERS[layer(module)]
    )
    assert upward == []


def test_no_two_modules_import_each_other():
    """No cycle, however long (Tarjan's strongly connected components)."""
    index: dict[str, int] = {}
    low: dict[str, int] = {}
    stack: list[str] = []
    cycles = []

    def visit(module: str) -> None:
        index[module] = low[module] = len(index)
        stack.append(module)
        for target in GRAPH[module]:
            if target not in index:
                visit(target)
                low[module] = min(low[module], low[target])
            elif target in stack:
                low[module] = min(low[module], index[target])
        if low[module] == index[module]:
            component = []
            while (top := stack.pop()) != module:
                component.append(top)
            if component:
                cycles.append(sorted([module, *component]))

    for module in MODULES:
        if module not in index:
            visit(module)
    assert cycles == []


def test_the_nodes_are_imported_only_from_above_them():
    importers = {
        module
        for module, targets in GRAPH.items()
        if any(t == 'fmm_ros.ros.nodes' or t.startswith('fmm_ros.ros.nodes.') for t in targets)
        and not module.startswith('fmm_ros.ros.nodes')
    }
    assert importers == NODES_IMPORTED_BY
