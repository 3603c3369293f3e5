"""Reference pages made from the code at build time, so they cannot drift from it.

Four directives, each walking the one declaration of what it documents:

- ``fmm-cli``: the `fmm` command from its argparse parser (`fmm_ros.cli.build_parser`),
  every subcommand and option with its help, default and choices;
- ``fmm-nodes``: every node in `fmm_ros.ros.nodes.NODES` with its `PARAMS` table (default,
  unit, range or choices, settable live or not), as `config/fmm_rig.yaml` is made from them;
- ``fmm-interfaces``: every message and service in `fmm_interfaces/msg` and `srv`, each field
  with the comment written above it in the `.msg`/`.srv` file;
- ``fmm-benchmarks``: every script in `benchmarks/` with the first paragraph of its docstring
  (read without importing it).

The directives build docutils nodes directly (no reStructuredText is generated and parsed),
so help strings with `*`, `_` or backquotes are shown as written.
"""

from __future__ import annotations

import argparse
import ast
import re
from collections.abc import Iterable, Sequence
from dataclasses import dataclass, field
from pathlib import Path

from docutils import nodes
from sphinx.application import Sphinx
from sphinx.util.docutils import SphinxDirective

REPO = Path(__file__).resolve().parents[2]
INTERFACES = REPO / 'fmm_interfaces'
BENCHMARKS = REPO / 'benchmarks'


def _section(directive: SphinxDirective, title: str, key: str) -> nodes.section:
    """A section titled `title` whose anchor is made from key (unique within the page)."""
    section = nodes.section(ids=[nodes.make_id(key)], names=[nodes.fully_normalize_name(key)])
    section += nodes.title(text=title)
    directive.state.document.note_implicit_target(section)
    return section


def _paragraph(*parts: str | nodes.Node) -> nodes.paragraph:
    """A paragraph of plain strings (shown as written) and inline nodes."""
    paragraph = nodes.paragraph()
    for part in parts:
        paragraph += nodes.Text(part) if isinstance(part, str) else part
    return paragraph


def _table(header: Sequence[str], rows: Iterable[Sequence[str | nodes.Node]]) -> nodes.table:
    """A table with a header row; a cell is plain text or an inline node (code, say)."""
    group = nodes.tgroup(cols=len(header))
    for _ in header:
        group += nodes.colspec(colwidth=1)
    head = nodes.thead()
    head += _row(header)
    group += head
    body = nodes.tbody()
    for row in rows:
        body += _row(row)
    group += body
    table = nodes.table()
    table += group
    return table


def _row(cells: Sequence[str | nodes.Node]) -> nodes.row:
    row = nodes.row()
    for cell in cells:
        entry = nodes.entry()
        entry += _paragraph(cell)
        row += entry
    return row


# The `fmm` command ----------------------------------------------------------------------------


def _subcommands(parser: argparse.ArgumentParser) -> list[tuple[str, argparse.ArgumentParser]]:
    """The subcommands a parser dispatches to, in the order its help lists them."""
    return [
        (name, sub)
        for action in parser._actions
        if isinstance(action, argparse._SubParsersAction)
        for name, sub in action.choices.items()
    ]


def _option_rows(parser: argparse.ArgumentParser) -> list[list[str | nodes.Node]]:
    """One row per option or positional: how it is written, what it does, its default."""
    formatter = parser._get_formatter()
    rows: list[list[str | nodes.Node]] = []
    for action in parser._actions:
        if isinstance(action, argparse._SubParsersAction | argparse._HelpAction):
            continue
        if action.help == argparse.SUPPRESS:
            continue
        written = formatter._format_action_invocation(action)
        help_text = formatter._expand_help(action) if action.help else ''
        if action.choices and not isinstance(action, argparse._SubParsersAction):
            help_text += f' (one of: {", ".join(map(str, action.choices))})'
        default = action.default
        shown = (
            ''
            if default in (None, argparse.SUPPRESS, False, [])
            or isinstance(action, argparse._VersionAction)
            else repr(default)
        )
        rows.append([nodes.literal(text=written), help_text.strip(), shown])
    return rows


def _parser_section(
    directive: SphinxDirective, command: str, parser: argparse.ArgumentParser
) -> nodes.section:
    """The section of one (sub)command: description, usage, options, then its subcommands."""
    section = _section(directive, command, f'cli-{command}')
    if parser.description:
        raw = parser.formatter_class is not argparse.HelpFormatter
        description = parser.description.strip()
        if raw and '\n' in description:
            section += nodes.literal_block(text=description)
        else:
            section += _paragraph(' '.join(description.split()))
    section += nodes.literal_block(text=parser.format_usage().strip(), language='text')
    rows = _option_rows(parser)
    if rows:
        section += _table(('option', 'what it does', 'default'), rows)
    if parser.epilog:
        section += _paragraph(' '.join(parser.epilog.split()))
    for name, sub in _subcommands(parser):
        section += _parser_section(directive, f'{command} {name}', sub)
    return section


class CliDirective(SphinxDirective):
    """``fmm-cli``: the whole `fmm` command, walked from its argparse parser."""

    def run(self) -> list[nodes.Node]:
        """One section per subcommand (nested for `fmm ros ...`)."""
        from fmm_ros.cli import build_parser

        parser = build_parser()
        result: list[nodes.Node] = [
            _paragraph(' '.join((parser.description or '').split())),
            nodes.literal_block(text=parser.format_usage().strip(), language='text'),
        ]
        result += [_parser_section(self, f'fmm {name}', sub) for name, sub in _subcommands(parser)]
        return result


# Nodes and their parameters ------------------------------------------------------------------


def _value_text(value: object) -> str:
    """A parameter's default as a params file would hold it."""
    if isinstance(value, str):
        return repr(value)
    if isinstance(value, list | tuple):
        return '[' + ', '.join(_value_text(item) for item in value) + ']'
    if isinstance(value, bool):
        return str(value).lower()
    return f'{value:g}' if isinstance(value, float) else str(value)


def _bounds_text(param: object) -> str:
    """The range or the choices of a parameter (empty when it has neither)."""
    limits = getattr(param, 'limits', None)
    choices = getattr(param, 'choices', ())
    parts = []
    if limits is not None:
        low, high = limits
        each = 'each ' if isinstance(param.default, list) else ''
        parts.append(f'{each}{_value_text(low)} to {_value_text(high)}')
    if choices:
        parts.append('one of ' + ', '.join(choices))
    return '; '.join(parts)


class NodesDirective(SphinxDirective):
    """``fmm-nodes``: every node of `NODES`, its summary line and its `PARAMS` table."""

    def run(self) -> list[nodes.Node]:
        """One section per node, in the order `NODES` lists them."""
        from fmm_ros.ros.nodes import NODES, node_module

        result: list[nodes.Node] = []
        for name in NODES:
            module = node_module(name)
            section = _section(self, name, f'node-{name}')
            summary = (module.__doc__ or '').strip().split('\n\n', 1)[0]
            section += _paragraph(' '.join(summary.split()))
            section += _paragraph(
                'Start: ',
                nodes.literal(text=f'ros2 run fmm_ros {name}'),
                ' (from the venv: ',
                nodes.literal(text=f'fmm ros run {name}'),
                '); module ',
                nodes.literal(text=module.__name__),
                '.',
            )
            rows = [
                [
                    nodes.literal(text=param.name),
                    _value_text(param.default),
                    param.description,
                    _bounds_text(param),
                    'no' if param.read_only else 'yes',
                ]
                for param in module.PARAMS
            ]
            section += _table(('parameter', 'default', 'meaning [unit]', 'range', 'live'), rows)
            result.append(section)
        return result


# Messages and services -----------------------------------------------------------------------


@dataclass
class FieldGroup:
    """Fields written under one comment in a .msg file (mu and mu_stderr share one, say)."""

    comment: list[str] = field(default_factory=list)
    fields: list[str] = field(default_factory=list)


@dataclass
class Part:
    """A message, or a service's request or response: its description and field groups."""

    description: list[str] = field(default_factory=list)
    groups: list[FieldGroup] = field(default_factory=list)


_FIELD = re.compile(r'^[A-Za-z][\w/]*(\[\d*\]|\[<=\d+\])?\s+\w+')


def parse_interface(text: str) -> list[Part]:
    """The parts of a .msg (one) or .srv (request, response) file, with their comments.

    A comment block followed by a blank line before any field describes the part; a comment
    directly above fields describes those fields.
    """
    parts = [Part()]
    comment: list[str] = []
    for raw in text.splitlines():
        line = raw.strip()
        if line == '---':
            parts.append(Part())
            comment = []
        elif line.startswith('#'):
            comment.append(line.lstrip('#').strip())
        elif not line:
            if comment and not parts[-1].groups:
                parts[-1].description += comment
                comment = []
        elif _FIELD.match(line):
            definition = line.split('#', 1)[0].strip()
            if comment or not parts[-1].groups:
                parts[-1].groups.append(FieldGroup(comment))
                comment = []
            parts[-1].groups[-1].fields.append(definition)
        else:
            raise ValueError(f'not a field, comment or separator: {raw!r}')
    return parts


class InterfacesDirective(SphinxDirective):
    """``fmm-interfaces``: every .msg and .srv file of fmm_interfaces, fields with comments."""

    def run(self) -> list[nodes.Node]:
        """A section per message, then per service (request and response tables)."""
        result: list[nodes.Node] = []
        for kind, suffix in (('msg', '.msg'), ('srv', '.srv')):
            for path in sorted((INTERFACES / kind).glob(f'*{suffix}')):
                self.env.note_dependency(str(path))
                name = f'fmm_interfaces/{kind}/{path.stem}'
                section = _section(self, name, f'{kind}-{path.stem}')
                parts = parse_interface(path.read_text(encoding='utf-8'))
                labels = ('',) if kind == 'msg' else ('Request', 'Response')
                for label, part in zip(labels, parts, strict=True):
                    if part.description:
                        section += _paragraph(' '.join(part.description))
                    if label:
                        section += _paragraph(nodes.strong(text=label))
                    rows = [
                        [nodes.literal(text='\n'.join(group.fields)), ' '.join(group.comment)]
                        for group in part.groups
                    ]
                    if rows:
                        section += _table(('field', 'meaning [unit]'), rows)
                result.append(section)
        return result


# Benchmarks -----------------------------------------------------------------------------------


class BenchmarksDirective(SphinxDirective):
    """``fmm-benchmarks``: each benchmark script, what its docstring says it measures."""

    def run(self) -> list[nodes.Node]:
        """A table: the script's command line and its docstring's first paragraph."""
        rows = []
        for path in sorted(BENCHMARKS.glob('*.py')):
            self.env.note_dependency(str(path))
            docstring = ast.get_docstring(ast.parse(path.read_text(encoding='utf-8'))) or ''
            summary = ' '.join(docstring.split('\n\n', 1)[0].split())
            rows.append([nodes.literal(text=f'benchmarks/{path.name}'), summary])
        return [_table(('script', 'what it measures'), rows)]


def setup(app: Sphinx) -> dict[str, object]:
    """Register the directives."""
    app.add_directive('fmm-cli', CliDirective)
    app.add_directive('fmm-nodes', NodesDirective)
    app.add_directive('fmm-interfaces', InterfacesDirective)
    app.add_directive('fmm-benchmarks', BenchmarksDirective)
    return {'parallel_read_safe': True, 'parallel_write_safe': True}
