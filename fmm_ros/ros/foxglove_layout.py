"""The rig's Foxglove layout, declared once with `foxglove.layouts`; the shipped file is its JSON.

The operator opens config/foxglove/fmm_rig_layout.json in Foxglove (Layouts, Import from
file) beside `fmm foxglove` or foxglove_bridge: live force and velocity (the live node's
points, peak per interval), the running mu with each impact's own, every impact's peak force
and impulse, the newest level's coherence over frequency, the last impact's full message and
the nodes' health. Time plots use the messages' header stamps, the graph's one time base
(signal time), so they line up at any rate_factor and in a bag.

Regenerate after changing a panel or a topic name::

    .venv/bin/python -m fmm_ros.ros.foxglove_layout

(test/test_foxglove.py checks the shipped file equals this declaration).
"""

import json
from pathlib import Path

import foxglove.layouts as fl

from fmm_ros.constants import (
    DIAGNOSTICS_TOPIC,
    FORCE,
    FRF_TOPIC,
    FRICTION_TOPIC,
    IMPACTS_TOPIC,
    LIVE_TOPICS,
    VELOCITY,
    resolve_name,
)

LAYOUT_FILE = Path(__file__).resolve().parents[2] / 'config' / 'foxglove' / 'fmm_rig_layout.json'
WINDOW_S = 40.0
"""Seconds of signal the live plots show: one hit and its decay (hits are 40 s apart)."""


def _topic(name: str) -> str:
    """A topic as Foxglove names it: resolved in the root namespace."""
    return resolve_name(name)


def _time_plot(title: str, series: list[tuple[str, str]], window_s: float | None) -> fl.PlotPanel:
    """A plot of (message path, label) series against their header stamps."""
    return fl.PlotPanel(
        title=title,
        config=fl.PlotConfig(
            paths=[
                fl.PlotSeries(value=path, label=label, timestamp_method='headerStamp')
                for path, label in series
            ],
            x_axis_val='timestamp',
            time_window_mode='sliding' if window_s else 'automatic',
            following_view_width=window_s,
            show_legend=True,
        ),
    )


def _live_plot(channel) -> fl.PlotPanel:
    """A channel's live points: the peak of each interval and its envelope."""
    topic = _topic(LIVE_TOPICS[channel.quantity])
    return _time_plot(
        f'{channel.quantity} [{channel.unit}], peak per interval (live)',
        [
            (f'{topic}.value', channel.quantity),
            (f'{topic}.minimum', 'min'),
            (f'{topic}.maximum', 'max'),
        ],
        WINDOW_S,
    )


def rig_layout() -> fl.Layout:
    """The rig's layout: streams on top, friction and impacts below, health at the side."""
    impacts, friction, frf = _topic(IMPACTS_TOPIC), _topic(FRICTION_TOPIC), _topic(FRF_TOPIC)
    coherence = fl.PlotPanel(
        title='coherence of the newest level [-] (needs two hits of a level)',
        config=fl.PlotConfig(
            paths=[fl.PlotSeries(value=f'{frf}.coherence[:]', label='coherence')],
            x_axis_val='currentCustom',
            x_axis_path=fl.PlotXAxisPath(value=f'{frf}.frequency_hz[:]'),
            x_axis_label='frequency [Hz]',
            min_y_value=0.0,
            max_y_value=1.05,
        ),
    )
    streams = fl.SplitContainer(
        direction='column',
        items=[
            fl.SplitItem(content=_live_plot(FORCE)),
            fl.SplitItem(content=_live_plot(VELOCITY)),
        ],
    )
    results = fl.SplitContainer(
        direction='row',
        items=[
            fl.SplitItem(
                content=_time_plot(
                    'mu [-]: running estimate and each impact alone',
                    [(f'{friction}.mu', 'running mu'), (f'{friction}.impact_mu', 'impact mu')],
                    None,
                )
            ),
            fl.SplitItem(
                content=_time_plot(
                    'impacts: peak force [N]',
                    [(f'{impacts}.peak_force_n', 'peak force')],
                    None,
                )
            ),
            fl.SplitItem(content=coherence),
        ],
    )
    side = fl.SplitContainer(
        direction='column',
        items=[
            fl.SplitItem(
                content=fl.RawMessagesPanel(
                    title='last impact',
                    config=fl.RawMessagesConfig(topic_path=impacts, expansion='none'),
                )
            ),
            fl.SplitItem(
                content=fl.DiagnosticsSummaryPanel(
                    title='health',
                    config=fl.DiagnosticsSummaryConfig(
                        topic_to_render=_topic(DIAGNOSTICS_TOPIC), sort_by_level=True
                    ),
                )
            ),
        ],
    )
    return fl.Layout(
        content=fl.SplitContainer(
            direction='row',
            items=[
                fl.SplitItem(
                    proportion=3,
                    content=fl.SplitContainer(
                        direction='column',
                        items=[
                            fl.SplitItem(proportion=3, content=streams),
                            fl.SplitItem(proportion=2, content=results),
                        ],
                    ),
                ),
                fl.SplitItem(proportion=1, content=side),
            ],
        )
    )


def layout_text() -> str:
    """The layout as the shipped file holds it: indented JSON, keys in declaration order."""
    return json.dumps(json.loads(rig_layout().to_json()), indent=2) + '\n'


if __name__ == '__main__':
    LAYOUT_FILE.parent.mkdir(parents=True, exist_ok=True)
    LAYOUT_FILE.write_text(layout_text(), encoding='utf-8')
    print(f'wrote {LAYOUT_FILE}')
