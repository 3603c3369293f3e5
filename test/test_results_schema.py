"""The results schema (`fmm_ros.core.results_schema`): each result field declared once.

The .msg/.srv comments are held to the units the schema declares (a drift is named, field by
field); the result dataclasses, the JSON key lists and the campaign's tidy columns are held
to its keys; the one rule for a value with its uncertainty is held in Python and in the
station page's port of it.
"""

import dataclasses
import json
import math
import re
import shutil
import subprocess
from pathlib import Path

import pytest

from fmm_ros.campaign.session import HitSummary, LevelRow
from fmm_ros.core import results_schema as schema
from fmm_ros.core.settings import settings_of
from fmm_ros.core.signal.analysis import ImpactAnalysis, LevelSummary
from fmm_ros.workflows import results

ROOT = Path(__file__).resolve().parents[1]
INTERFACES = ROOT / 'fmm_interfaces'
STATION_JS = ROOT / 'fmm_ros' / 'station' / 'static' / 'station.js'

GROUPS = {
    'impact': schema.IMPACT,
    'level': schema.LEVEL_FIELDS,
    'fit': schema.FIT,
    'diagnosis': schema.DIAGNOSIS,
}
DECLARED = [
    field
    for group in (*GROUPS.values(), {f.name: f for f in schema.FIT_IMPACT})
    for field in group.values()
]


def message_comments(path: Path) -> dict[str, str]:
    """Each field of a .msg/.srv file -> the comment block written above it (or its group)."""
    comments, block, after_field = {}, [], False
    for raw in path.read_text(encoding='utf-8').splitlines():
        line = raw.strip()
        if not line or line == '---':
            block, after_field = [], False
        elif line.startswith('#'):
            if after_field:  # a new comment after fields starts a new block
                block, after_field = [], False
            block.append(line.lstrip('#').strip())
        else:
            name = line.split()[1]
            comments[name] = ' '.join(block)
            after_field = True
    return comments


def declared_message_fields() -> list[tuple[schema.ResultField, str, str]]:
    found = []
    for field in DECLARED:
        for target in field.messages:
            message, name = target.split('.')
            found.append((field, message, name))
    return sorted(set(found), key=lambda item: (item[1], item[2], item[0].name))


def interface_file(message: str) -> Path:
    for folder in ('msg', 'srv'):
        path = INTERFACES / folder / f'{message}.{folder}'
        if path.is_file():
            return path
    raise AssertionError(f'the schema names {message}, which fmm_interfaces does not define')


def test_every_message_field_the_schema_names_exists_and_carries_its_unit():
    """Names the drift: a field the schema maps that the message lacks, or a unit not written."""
    drift = []
    for field, message, name in declared_message_fields():
        comments = message_comments(interface_file(message))
        if name not in comments:
            drift.append(f'{message}.{name}: no such field (schema {field.name})')
            continue
        if field.unit and f'[{field.unit}]' not in comments[name]:
            drift.append(
                f'{message}.{name}: the comment does not give [{field.unit}] '
                f'(schema {field.name}): {comments[name]!r}'
            )
    assert drift == []
    assert len(declared_message_fields()) >= 40


def test_the_drift_check_names_a_wrong_unit(tmp_path):
    """The check can fail: a comment giving another unit is not taken as the declared one."""
    path = tmp_path / 'Bad.msg'
    path.write_text('# Impulse of the hit [N].\nfloat64 impulse_n_s\n', encoding='utf-8')
    comments = message_comments(path)
    assert f'[{schema.IMPULSE.unit}]' not in comments['impulse_n_s']


def test_impact_id_has_the_meaning_of_the_message_and_of_stable_impact_id():
    from fmm_ros.core.signal.records import stable_impact_id

    comment = message_comments(INTERFACES / 'msg' / 'ImpactResult.msg')['impact_id']
    assert "trigger's acquisition time in ms modulo 2^32" in comment
    assert "trigger's acquisition time in ms modulo 2^32" in schema.IMPACT_ID.help
    assert 'acquisition time in ms, modulo 2**32' in stable_impact_id.__doc__


def test_the_result_dataclasses_take_unit_and_help_from_the_schema():
    for cls, group in ((ImpactAnalysis, schema.IMPACT), (LevelSummary, schema.LEVEL_FIELDS)):
        declared = {item.name: item for item in settings_of(cls)}
        for field in group.values():
            assert declared[field.name].help == field.help, field.name
            assert declared[field.name].unit == ('' if field.unit == '-' else field.unit)


def test_json_keys_and_tidy_columns_are_the_schema_keys():
    assert results.HIT_FIELDS == schema.keys(schema.HIT_RECORD)
    assert results.LEVEL_FIELDS == schema.keys(schema.LEVEL_RECORD)
    assert set(schema.keys(schema.HIT_RECORD)) <= set(schema.IMPACT)
    assert set(schema.keys(schema.LEVEL_RECORD)) <= set(schema.LEVEL_FIELDS)
    hit_columns = [f.name for f in dataclasses.fields(HitSummary)]
    own = {'source', 'mu', 'mu_stderr', 'residual_rms_m_s'}
    assert [name for name in hit_columns if name not in own] == list(results.HIT_FIELDS)
    level_columns = [f.name for f in dataclasses.fields(LevelRow)]
    assert [name for name in level_columns if name != 'coherence_at_peak'] == list(
        results.LEVEL_FIELDS
    )


def test_each_key_is_declared_once_per_group():
    for name, group in GROUPS.items():
        assert all(key == field.name for key, field in group.items()), name
        assert all(field.help and field.words for field in group.values()), name


@pytest.mark.parametrize(
    'field, shown, ascii_text',
    [
        (schema.IMPULSE, 'impulse [N·s]', 'impulse [N*s]'),
        (schema.MEAN_IMPULSE, 'mean impulse [N·s]', 'mean impulse [N*s]'),
        (schema.PEAK_RECEPTANCE, 'peak |X/F| [mm/N]', 'peak |X/F| [mm/N]'),
        (schema.CONTACT_DURATION, 'contact [ms]', 'contact [ms]'),
        (schema.NATURAL_FREQUENCY, 'f_n [Hz]', 'f_n [Hz]'),
        (schema.LEVEL, 'level', 'level'),
        (schema.COUNT, 'hits', 'hits'),
    ],
)
def test_one_label_rule(field, shown, ascii_text):
    assert schema.label(field) == shown
    assert schema.label(field, ascii=True) == ascii_text


UNCERTAIN = [
    (0.11300046, 4.6e-07, '0.11300046 ± 0.00000046'),
    (0.1130004, 1.4e-06, '0.1130004 ± 0.0000014'),
    (0.1126, 0.0021, '0.1126 ± 0.0021'),
    (0.982, 0.023, '0.982 ± 0.023'),
    (1404.0, 15.0, '1404 ± 15'),
    (0.113, 0.0, '0.113'),
    (0.113, math.nan, '0.113'),
]


@pytest.mark.parametrize('value, std, text', UNCERTAIN)
def test_a_value_is_printed_to_the_second_significant_digit_of_its_uncertainty(value, std, text):
    assert schema.format_with_uncertainty(value, std) == text
    assert schema.format_with_uncertainty(value, std, ' +- ') == text.replace(' ± ', ' +- ')


def _station_functions(*names: str) -> str:
    source = STATION_JS.read_text(encoding='utf-8')
    parts = []
    for name in names:
        start = source.index(f'function {name}(')
        parts.append(source[start : source.index('\n}\n', start) + 3])
    return '\n'.join(parts)


def _node(script: str) -> object:
    node = shutil.which('node')
    assert node, 'node is needed to run the station page functions'
    out = subprocess.run([node, '-e', script], capture_output=True, text=True, check=True)
    return json.loads(out.stdout)


def test_the_station_prints_uncertainty_by_the_same_rule():
    cases = [(v, s) for v, s, _ in UNCERTAIN if math.isfinite(s)]
    shown = f'{json.dumps(cases)}.map(([v, s]) => withUncertainty(v, s))'
    script = _station_functions('withUncertainty') + f'\nconsole.log(JSON.stringify({shown}));'
    assert _node(script) == [schema.format_with_uncertainty(v, s) for v, s in cases]


@pytest.mark.parametrize('step', [2e-7, 2.5e-7, 5e-4, 0.01, 0.5])
def test_the_station_running_mu_ticks_tell_their_steps_apart(step):
    """Ticks 1e-6 apart around 0.113 must not all read 0.113; each shows its own value."""
    splits = [0.113 + (k - 2) * step for k in range(5)]
    script = _station_functions('spanTicks') + (
        f'\nconsole.log(JSON.stringify(spanTicks(null, {json.dumps(splits)})));'
    )
    ticks = _node(script)
    assert len(set(ticks)) == len(ticks)
    for tick, value in zip(ticks, splits, strict=True):
        assert float(tick) == pytest.approx(value, abs=step * 1e-6)
    decimals = {len(tick.split('.')[1]) if '.' in tick else 0 for tick in ticks}
    assert len(decimals) == 1 and max(decimals) <= 12


def test_the_schema_module_imports_only_the_standard_library_and_the_base():
    source = (ROOT / 'fmm_ros' / 'core' / 'results_schema.py').read_text(encoding='utf-8')
    imported = set(re.findall(r'^(?:from|import) ([\w.]+)', source, flags=re.M))
    assert imported <= {
        '__future__',
        'dataclasses',
        'math',
        'typing',
        'fmm_ros.constants',
        'fmm_ros.core.settings',
    }
