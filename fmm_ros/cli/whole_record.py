"""`--whole-record`: `fmm diagnose`, `fmm fit` and `fmm identify-rig` on records without hits.

Each lab file is one excitation; its force and displacement channels are read as every command
reads them (`fmm_ros.units.channel_factor`), the record fitted by output error
(`fmm_ros.workflows.whole_record`), and one JSON document printed per file (a list for
several), or a few lines of text. Exit status: 0 every record described, 1 some record's model
leaves more than a tenth of its displacement unexplained (`fits_record` false, `why`), 2 bad
input.
"""

from __future__ import annotations

import argparse
import json
import sys


def run(args: argparse.Namespace, command: str) -> int:
    """Analyse each input as one excitation; print JSON or text."""
    from fmm_ros.workflows.whole_record import analyse_whole_record, read_whole_record

    fit_rig = command == 'identify-rig' or getattr(args, 'fit_rig', False)
    rig = None
    if not fit_rig:
        from fmm_ros.cli.options import rig_from_args

        constants = rig_from_args(args)
        rig = {
            'mass': constants.mass_kg,
            'damping': constants.damping_n_s_per_m,
            'stiffness': constants.stiffness_n_per_m,
        }
    documents = []
    for path in args.inputs:
        record = read_whole_record(
            path,
            force=args.force,
            displacement=args.displacement,
            force_unit=args.force_unit,
            displacement_unit=args.displacement_unit,
            force_scale=args.force_scale,
            displacement_scale=args.displacement_scale,
            time=args.time,
            sample_rate_hz=args.sample_rate_hz,
        )
        documents.append(analyse_whole_record(record, command, rig))
    if args.json:
        json.dump(documents[0] if len(documents) == 1 else documents, sys.stdout, indent=2)
        print()
    else:
        print('\n'.join(text_report(document) for document in documents))
    return 0 if all(document['fits_record'] for document in documents) else 1


def text_report(document: dict) -> str:
    """The rig, the resonance, the named terms and the gap, in the units used."""
    units, rig = document['units'], document['rig']
    how = 'rig fitted' if document['fitted_rig'] else 'rig given'
    lines = [
        f'{document["file"]}: whole record, {document["samples"]} samples at '
        f'{document["sample_rate_hz"]:g} Hz ({how})',
        f'  m = {rig["mass_kg"]:.5g} ± {rig["mass_kg_stderr"]:.2g} {units["mass_kg"]}',
        f'  c = {rig["damping_n_s_per_m"]:.5g} ± {rig["damping_n_s_per_m_stderr"]:.2g} '
        f'{units["damping_n_s_per_m"]}',
        f'  k = {rig["stiffness_n_per_m"]:.5g} ± {rig["stiffness_n_per_m_stderr"]:.2g} '
        f'{units["stiffness_n_per_m"]}',
        f'  linear resonance sqrt(k/m)/2pi = {document["natural_frequency_hz"]:.4g} Hz',
    ]
    for term, values in document['terms'].items():
        key = next(name for name in values if not name.endswith('_stderr'))
        lines.append(f'  {term}: {values[key]:.5g} ± {values[key + "_stderr"]:.2g} {units[key]}')
    lines.append(
        f'  named: {", ".join(document["named"])}; gap {document["gap_before"]:.4g} -> '
        f'{document["gap_after"]:.4g}'
    )
    lines += [f'  not named: {term}: {why}' for term, why in document['not_named'].items()]
    if not document['fits_record']:
        lines.append(f'  does not fit the record: {document["why"]}')
    return '\n'.join(lines)
