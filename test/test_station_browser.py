"""The station page in headless Chromium against the multi-process rig.

Every node is its own process, as `ros2 run` starts them; the page is the real one, served by
the station node and driven by Playwright as an operator would. Asserted: each hit is on the
page within 1 s of its ImpactResult (both clocks are this machine's); rejecting a hit on the
page takes it out of the fitter's running mu and its fit (their impact ids say so), and
accepting it puts it back; bad input gets a clear message on the page; the metadata form
reaches the bag; the page reconnects by itself after the station restarts and shows the hits
of a new session after the sources restart. FMM_STATION_SCREENSHOT=path also saves the
screenshot there (docs/img/station.png is made so).
"""

import os
import shutil
import socket
import time
from pathlib import Path

import pytest
from browser import CHROMIUM_ARGS, chromium_path
from playwright.sync_api import sync_playwright
from rclpy.node import Node
from rig_graph import wait_for

from fmm_interfaces.msg import FrfSummary, FrictionEstimate, ImpactResult
from fmm_interfaces.srv import FitFriction
from fmm_ros.constants import FIT_SERVICE, FRF_TOPIC, FRICTION_TOPIC, IMPACTS_TOPIC
from fmm_ros.io.bags.metadata import read_information
from fmm_ros.io.bags.reader import BagReader
from fmm_ros.io.session_info import SESSION_KEY, from_json
from fmm_ros.ros.graph import InProcessGraph, private_domain_id
from fmm_ros.ros.launch import (
    SIMULATED_RIG,
    default_params_file,
    parse_overrides,
    start_processes,
    stop_processes,
    with_wiring,
)
from fmm_ros.ros.qos import RESULT_QOS

pytestmark = [pytest.mark.ros, pytest.mark.slow]

RIG = (*SIMULATED_RIG, 'station')
SOURCES = ('hammer_sim', 'rig_sim')
LATENCY_S = 1.0


class Watcher(Node):
    """Impact results and running-mu estimates, each with the wall time it arrived."""

    def __init__(self, **kwargs):
        super().__init__('watcher', **kwargs)
        self.impacts: list[tuple[ImpactResult, float]] = []
        self.friction: list[FrictionEstimate] = []
        self.levels: dict[str, FrfSummary] = {}
        self.create_subscription(
            FrfSummary, FRF_TOPIC, lambda m: self.levels.__setitem__(m.level, m), RESULT_QOS
        )
        self.create_subscription(
            ImpactResult, IMPACTS_TOPIC, lambda m: self.impacts.append((m, time.time())), RESULT_QOS
        )
        self.create_subscription(FrictionEstimate, FRICTION_TOPIC, self.friction.append, RESULT_QOS)
        self.fit = self.create_client(FitFriction, FIT_SERVICE)


def free_port() -> int:
    with socket.socket() as probe:
        probe.bind(('127.0.0.1', 0))
        return probe.getsockname()[1]


class Rig:
    """The simulated rig and the station as separate processes, each restartable."""

    def __init__(self, tmp_path: Path, hits_per_level: int):
        self.port = free_port()
        self.bag = tmp_path / 'bag'
        self.overrides = with_wiring(
            RIG,
            parse_overrides(
                [
                    'hammer_sim.rate_factor=4',
                    f'hammer_sim.hits_per_level={hits_per_level}',
                    'hammer_sim.batch_size=1000',
                    'hammer_sim.hit_spacing_s=8.0',
                    'hammer_sim.first_hit_s=1.0',
                    'analyzer.window_s=6.0',
                    f'recorder.bag_path={self.bag}',
                    f'station.port={self.port}',
                    f'station.target_hits_per_level={hits_per_level}',
                ],
                RIG,
            ),
        )
        self.processes: dict[str, object] = {}

    @property
    def url(self) -> str:
        return f'http://127.0.0.1:{self.port}/'

    def start(self, *names: str) -> None:
        for name, process in zip(
            names, start_processes(names, default_params_file(), self.overrides), strict=True
        ):
            self.processes[name] = process

    def stop(self, *names: str) -> list[int]:
        """Stop these nodes (default all) in the launcher's order; their exit codes.

        A generous SIGTERM deadline: what is asserted is that each node closes cleanly on
        SIGINT, not how fast a loaded 2-core machine gets there.
        """
        names = names or tuple(self.processes)
        return stop_processes(
            [self.processes.pop(n) for n in names], nodes=list(names), sigterm_timeout_s=30.0
        )


@pytest.fixture
def rig(tmp_path, monkeypatch, request):
    monkeypatch.setenv('ROS_DOMAIN_ID', str(private_domain_id()))
    monkeypatch.setenv('ROS_AUTOMATIC_DISCOVERY_RANGE', 'LOCALHOST')
    made = Rig(tmp_path, request.param)
    yield made
    if made.processes:
        made.stop()


@pytest.fixture
def browser_page():
    with sync_playwright() as playwright:
        browser = playwright.chromium.launch(
            executable_path=chromium_path(), headless=True, args=list(CHROMIUM_ARGS)
        )
        page = browser.new_page(viewport={'width': 1500, 'height': 1300})
        page.problems = []
        page.on('pageerror', lambda error: page.problems.append(f'script error: {error}'))
        yield page
        browser.close()


def open_station(page, rig: Rig) -> None:
    assert wait_for(lambda: _listening(rig.port), timeout_s=60.0), 'the station never listened'
    page.goto(rig.url, wait_until='load')
    page.wait_for_function("document.getElementById('connection').textContent === 'live'")


def _listening(port: int) -> bool:
    with socket.socket() as probe:
        return probe.connect_ex(('127.0.0.1', port)) == 0


def page_ids(page) -> list[int]:
    return page.evaluate('Object.keys(window.stationPage.hitSeen).map(Number)')


@pytest.mark.parametrize('rig', [2], indirect=True)
def test_hits_appear_within_a_second_and_a_rejected_hit_leaves_the_mu(rig, browser_page, tmp_path):
    page = browser_page
    with InProcessGraph(domain_id=int(os.environ['ROS_DOMAIN_ID'])) as graph:
        watcher = graph.add(Watcher)
        graph.start()
        rig.start('station')
        open_station(page, rig)
        opened = time.time()
        rig.start(*SIMULATED_RIG)
        assert wait_for(lambda: len(watcher.impacts) == 6, timeout_s=120.0), watcher.impacts
        ids = [msg.impact_id for msg, _ in watcher.impacts]
        page.wait_for_function(
            f'{ids}.every((id) => id in window.stationPage.hitSeen)', timeout=10_000
        )
        seen = page.evaluate('window.stationPage.hitSeen')
        # Each hit on the page within 1 s of its ImpactResult.
        for msg, arrived in watcher.impacts:
            assert arrived > opened
            assert seen[str(msg.impact_id)] / 1e3 - arrived < LATENCY_S
        accepted = [m.impact_id for m, _ in watcher.impacts if m.accepted]
        assert wait_for(
            lambda: watcher.friction and set(accepted) <= set(watcher.friction[-1].impact_ids),
            timeout_s=60.0,
        ), 'the fitter never held every accepted hit in its running mu'
        target = accepted[1]

        page.fill('#operator', 'kb')
        page.fill('#reason', 'hammer slipped')
        page.click(f'#hits tr[data-id="{target}"] button.reject')
        assert wait_for(lambda: target not in watcher.friction[-1].impact_ids, timeout_s=10.0)
        last = watcher.friction[-1]
        assert last.impact_id == target and last.count == len(accepted) - 1
        page.wait_for_function(
            f"!document.getElementById('mu').dataset.ids.split(',').includes('{target}')"
        )
        # The hit's row follows the decision's echo, the mu the fitter's answer to it: two
        # streams with no order between them, so the row is waited for too.
        page.wait_for_function(
            f"document.querySelector('#hits tr[data-id=\"{target}\"]').dataset.taken === 'no'"
        )
        row = page.locator(f'#hits tr[data-id="{target}"]')
        assert row.get_attribute('data-taken') == 'no'
        assert 'reject by kb: hammer slipped' in row.inner_text()
        fit = graph.call(watcher.fit, FitFriction.Request(), timeout_s=120.0)
        assert fit.success, fit.message
        assert target not in fit.impact_ids and set(fit.impact_ids) == set(accepted) - {target}
        assert f'impact {target} rejected by kb (hammer slipped)' in fit.message
        level = next(m.level for m, _ in watcher.impacts if m.impact_id == target)
        assert wait_for(lambda: target not in watcher.levels[level].impact_ids, timeout_s=10.0)

        page.click(f'#hits tr[data-id="{target}"] button.accept')  # reversible
        assert wait_for(lambda: target in watcher.friction[-1].impact_ids, timeout_s=10.0)

        # Bad input: a clear message on the page, nothing changed.
        page.evaluate("judge(99999, 'reject')")
        page.wait_for_function("document.getElementById('banner').textContent.includes('99999')")
        assert 'not a hit this station has seen' in page.inner_text('#banner')
        page.fill('textarea[name=notes]', 'n' * 2001)
        page.click('#session-form button[type=submit]')
        page.wait_for_function(
            "document.getElementById('banner').textContent.includes('at most 2000')"
        )
        page.fill('textarea[name=notes]', 'run-in done')
        page.fill('input[name=operator_name]', 'kb')
        page.fill('input[name=lubricant]', 'ISO VG 32')
        page.fill('input[name=normal_load_n]', '6.67')
        page.click('#session-form button[type=submit]')
        page.wait_for_function(
            "document.getElementById('session-saved').textContent.includes('lubricant ISO VG 32')"
        )
        page.wait_for_function(
            "document.getElementById('recording').textContent.includes('messages')"
        )
        shot = tmp_path / 'station.png'
        page.screenshot(path=str(shot), full_page=True)
        if os.environ.get('FMM_STATION_SCREENSHOT'):
            shutil.copy(shot, os.environ['FMM_STATION_SCREENSHOT'])
        assert shot.stat().st_size > 20_000
        assert page.problems == []
        codes = rig.stop()
    assert codes == [0] * len(codes), codes
    info = from_json(read_information(rig.bag)['custom_data'][SESSION_KEY])
    assert (info['operator_name'], info['normal_load_n']) == ('kb', 6.67)
    with BagReader(rig.bag) as reader:
        assert reader.topics['/fmm/impact_decisions'].count == 2


@pytest.mark.parametrize('rig', [1], indirect=True)
def test_the_page_reconnects_after_the_station_or_the_sources_restart(rig, browser_page):
    page = browser_page
    rig.start('station')
    open_station(page, rig)
    rig.start(*SIMULATED_RIG)
    page.wait_for_function('Object.keys(window.stationPage.hitSeen).length >= 2', timeout=120_000)

    rig.stop('station')
    page.wait_for_function("document.getElementById('connection').textContent === 'reconnecting'")
    rig.start('station')
    page.wait_for_function(
        "document.getElementById('connection').textContent === 'live'", timeout=60_000
    )
    # The new station's snapshot lists the hits again (the analyzer keeps them for late
    # subscribers).
    page.wait_for_function('document.querySelectorAll("#hits tbody tr").length >= 2')

    # A new session from restarted sources: its hits reach the page through the same page.
    rig.stop(*SOURCES)
    newest = max(page_ids(page))
    rig.start(*SOURCES)
    page.wait_for_function(
        f'Math.max(...Object.keys(window.stationPage.hitSeen).map(Number)) > {newest}',
        timeout=120_000,
    )
    assert page.inner_text('#connection') == 'live'
    assert page.problems == []
