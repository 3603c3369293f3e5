"""The campaign table: CSV and YAML, column kinds, the rig a row sets, and clear refusals."""

import datetime as dt

import pytest

from fmm_ros.campaign.table import DATE, NUMBER, TEXT, format_value, read_campaign_table
from fmm_ros.core.physics.rig import FMM_RIG


def write(path, text):
    path.write_text(text, encoding='utf-8')
    return path


def test_a_csv_table_gives_sessions_conditions_kinds_and_rigs(tmp_path):
    table = read_campaign_table(
        write(
            tmp_path / 'campaign.csv',
            '\ufeff# lubricant study, autumn\n'
            'session,id,lubricant,normal_force_n,date,notes\n'
            'bags/a1,A1,PTFE-A,6.67,2026-11-02,\n'
            '\n'
            'csv/b1,,PTFE-B,9.81,2026-11-03T14:30,new counterface\n'
            'csv/b2,B2,PTFE-B,,2026-11-04\n',
        )
    )
    assert [s.session_id for s in table.sessions] == ['A1', 'csv/b1', 'B2']
    assert [s.row for s in table.sessions] == [3, 5, 6]
    assert {c.name: c.kind for c in table.columns} == {
        'lubricant': TEXT,
        'normal_force_n': NUMBER,
        'date': DATE,
    }
    first, second, third = table.sessions
    assert first.spec.source == tmp_path / 'bags/a1'
    assert first.conditions == {
        'lubricant': 'PTFE-A',
        'normal_force_n': 6.67,
        'date': dt.datetime(2026, 11, 2),
    }
    # The load column sets the rig of that session's fit; an empty one leaves the base rig.
    assert first.spec.rig.normal_force_n == 6.67 and second.spec.rig.normal_force_n == 9.81
    assert third.spec.rig == FMM_RIG and third.conditions['normal_force_n'] is None
    assert first.spec.rig.mass_kg == FMM_RIG.mass_kg
    assert second.notes == 'new counterface'
    assert table.default_by() == ('lubricant', 'normal_force_n')
    assert format_value(second.conditions['date']) == '2026-11-03T14:30:00'


def test_a_semicolon_table_and_a_yaml_table_read_alike(tmp_path):
    csv_table = read_campaign_table(
        write(tmp_path / 'a.csv', 'session;lubricant;normal_force_n\ns1;A;6.67\ns2;B;9.81\n')
    )
    yaml_table = read_campaign_table(
        write(
            tmp_path / 'a.yaml',
            'title: Lubricants\nby: lubricant\ntrend: [normal_force_n]\n'
            'mapping: maps/daq.yaml\nsessions:\n'
            '  - {session: s1, lubricant: A, normal_force_n: 6.67}\n'
            '  - {session: s2, lubricant: B, normal_force_n: 9.81, date: 2026-11-02}\n',
        )
    )
    for table in (csv_table, yaml_table):
        assert [s.conditions['lubricant'] for s in table.sessions] == ['A', 'B']
        assert [s.spec.rig.normal_force_n for s in table.sessions] == [6.67, 9.81]
    assert yaml_table.title == 'Lubricants'
    assert (yaml_table.by, yaml_table.trend) == (('lubricant',), ('normal_force_n',))
    assert yaml_table.sessions[0].spec.mapping == tmp_path / 'maps/daq.yaml'
    assert yaml_table.sessions[1].conditions['date'] == dt.datetime(2026, 11, 2)
    assert yaml_table.column('date').kind == DATE


@pytest.mark.parametrize(
    ('text', 'message'),
    [
        ('lubricant\nA\n', 'no "session" column'),
        ('session,id\ns1,x\ns2,x\n', "session id\\(s\\) 'x' appear more than once"),
        ('session,normal_force_n\ns1,heavy\n', "'normal_force_n' sets the rig and must be numeric"),
        ('session,normal_force_n\ns1,-2\n', 'row 2: normal_force_n must not be negative'),
        ('session,mass_kg\ns1,0\n', 'row 2: mass_kg must be positive'),
        ('session,lubricant\n,A\n', 'row 2: no session given'),
        ('session,lubricant\ns1,A,extra\n', 'row 2 has 3 cells for 2 columns'),
        ('session,a,a\ns1,1,2\n', 'unique, non-empty column names'),
        ('# only a comment\n', 'lists no session'),
    ],
)
def test_a_bad_csv_table_is_refused_naming_the_problem(tmp_path, text, message):
    with pytest.raises(ValueError, match=message):
        read_campaign_table(write(tmp_path / 'bad.csv', text))


@pytest.mark.parametrize(
    ('text', 'message'),
    [
        ('sessions: {session: s1}\n', 'expected a list of sessions'),
        ('sesions: []\n', 'unknown key\\(s\\) sesions'),
        ('by: 3\nsessions:\n  - {session: s1}\n', '"by" must be a column name'),
        ('by: [lube]\nsessions:\n  - {session: s1, lubricant: A}\n', "no condition column 'lube'"),
        ('- {session: s1, lubricant: [A, B]}\n', 'a table cell must be a single value'),
    ],
)
def test_a_bad_yaml_table_is_refused_naming_the_problem(tmp_path, text, message):
    with pytest.raises(ValueError, match=message):
        read_campaign_table(write(tmp_path / 'bad.yaml', text))


def test_a_column_mixing_numbers_and_words_is_text(tmp_path):
    table = read_campaign_table(
        write(tmp_path / 'c.csv', 'session,counterface,batch\ns1,steel,12\ns2,steel,12b\n')
    )
    assert table.column('batch').kind == TEXT
    assert [s.conditions['batch'] for s in table.sessions] == ['12', '12b']
    with pytest.raises(ValueError, match="no condition column 'load'.*counterface, batch"):
        table.column('load')
