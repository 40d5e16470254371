"""The tuner driving a drive (``pmsm2dof tune SCENARIO --link URL``), in a real headless Chromium.

The drive is the PC's virtual drive of the small servo (20 kHz current, 2 kHz speed loop): the
firmware (foc.c, link.c) over the engine's plant, its XCP slave on TCP, built once for the
module. The tuner's session on it is the one ``pmsm2dof tune --link`` opens
(:func:`pmsm2dof.ui.tuner.drive_session`), and the page is driven as a person would: type a new
alpha, arm, run, read the plots' data.

Truth from outside the code under test: the engine's simulation of the scenario with the new
alpha, computed here (the drive is the firmware's C over the plant; the engine the controllers
over the same plant without the firmware's float32 Clarke and Park transforms and duty-cycle
round trip: their traces differ by 2e-9 to 4e-7 of the step, docs/mcu.md, so the project's bound
of 1e-4 of the step, :data:`pmsm2dof.studies.firmware.AGREEMENT`, is the tolerance: decimation
picks samples and does not average, so the bound holds on the plotted points too); the drive's
alpha read back over XCP by a new master after the tuner closed its link; the drive's own run
state (``link_status_now``) read the same way after a lost page or a dropped link.
"""

import contextlib
import shutil
import socket
import threading
import time
from pathlib import Path

import numpy as np
import pytest

from pmsm2dof.drive.link import Link
from pmsm2dof.drive.serve import serve_host
from pmsm2dof.sim.scenario import load_scenario
from pmsm2dof.sim.simulate import Simulation
from pmsm2dof.studies.bench import HEARTBEAT_TIMEOUT_S
from pmsm2dof.studies.firmware import AGREEMENT, build_firmware
from pmsm2dof.ui.tuner import create_app, drive_session, serving_in_thread

pytest.importorskip("pyxcp")
CHROMIUM = Path("/usr/bin/chromium")
if not CHROMIUM.exists():
    pytest.skip("Debian's chromium is not installed at /usr/bin/chromium", allow_module_level=True)
sync_api = pytest.importorskip("playwright.sync_api", reason="playwright for Python is not installed")
_MISSING = [t for t in ("cmake", "cc") if shutil.which(t) is None]

#: Slow (a firmware build and a browser): the full suite.
pytestmark = [pytest.mark.slow, pytest.mark.skipif(bool(_MISSING), reason=f"{', '.join(_MISSING)} not installed")]

ROOT = Path(__file__).resolve().parents[1]
SERVO = ROOT / "examples" / "firmware" / "small-servo-20k.toml"
CHROMIUM_ARGS = ["--no-sandbox", "--disable-gpu", "--disable-background-networking", "--no-first-run"]
ALPHA = "speed_controller.alpha_radps"
#: The drive's link watchdog in the runs on the wall clock [ms]: the tuner polls every 20 ms, but on a loaded
#: machine (a browser and the tests on two cores) a poll can come late by more than the virtual board's 200 ms.
LINK_TIMEOUT_MS = 2000


@pytest.fixture(scope="module")
def servo(tmp_path_factory):
    """The small servo and its PC virtual drive, built once."""
    scenario = load_scenario(str(SERVO))
    return scenario, build_firmware(scenario, tmp_path_factory.mktemp("servo") / "fw", mcu=False).folder


@pytest.fixture(scope="module")
def browser():
    with sync_api.sync_playwright() as playwright:
        browser = playwright.chromium.launch(executable_path=str(CHROMIUM), args=CHROMIUM_ARGS)
        yield browser
        browser.close()


@contextlib.contextmanager
def tuner_on(browser, scenario, url, a2l):
    """The tuner in drive mode on the drive at ``url``, served and open in a page; yields (page, app)."""
    with drive_session(scenario, url, a2l) as session, serving_in_thread(create_app(scenario, drive=session)) as at:
        page = browser.new_page(viewport={"width": 1440, "height": 900})
        errors = []
        page.on("pageerror", lambda exc: errors.append(str(exc)))
        page.goto(at)
        page.wait_for_function("window.tuner.renderCount > 0 && window.tuner.drive !== null", timeout=30000)
        yield page, session
        if not page.is_closed():
            page.close()
        assert not errors, errors


def type_value(page, key, value):
    """Type a control's value and wait until the tuner redrew it."""
    renders = page.evaluate("window.tuner.renderCount")
    box = page.locator(f'input[name="{key}"]')
    box.fill(str(value))
    box.press("Enter")
    page.wait_for_function(f"!window.tuner.pending && window.tuner.renderCount > {renders}", timeout=30000)


def arm(page):
    writes = page.evaluate("window.tuner.drive.writes")
    page.check("#drive-arm")
    page.wait_for_function(f"window.tuner.drive.armed && window.tuner.drive.writes > {writes}", timeout=30000)


def drive_status(url, elf):
    """The drive's run status and alpha, read by a master of its own."""
    with Link(url, elf) as link:
        return link.status(), link.read("link_speed_config.alpha_radps")


def engine_speed(scenario, alpha_radps):
    """The engine's speed [rpm] of the scenario with another alpha, at every speed sample."""
    sim = Simulation(scenario.with_overrides({ALPHA: alpha_radps}))
    sim.advance(sim.n_samples)
    result = sim.result(scenario, 0.0)
    return np.asarray(result.t_s), np.asarray(result.speed_rpm), np.asarray(result.speed_ref_rpm)


def test_the_page_writes_alpha_runs_the_drive_and_draws_it_over_its_twin(servo, browser):
    scenario, folder = servo
    elf = folder / "virtual_drive_host"
    a2l = folder / "virtual_drive_host.a2l"
    alpha = 100.0
    with serve_host(elf, realtime=False) as url:
        with tuner_on(browser, scenario, url, a2l) as (page, session):
            arm(page)
            writes = page.evaluate("window.tuner.drive.writes")
            type_value(page, ALPHA, alpha)
            page.wait_for_function(f"window.tuner.drive.writes > {writes}", timeout=30000)
            assert page.evaluate("window.tuner.drive.written.alpha_radps") == alpha
            assert "written" in page.locator("#drive-status").inner_text()
            page.click("#drive-run")
            page.wait_for_function("window.tuner.drive.runs === 1", timeout=60000)
            plotted = page.evaluate(
                "Object.fromEntries(document.getElementById('drive-plot').data.map((d) => [d.name, [d.x, d.y]]))"
            )
            rows = page.evaluate(
                """Object.fromEntries([...document.querySelectorAll('#drive-metrics tr[data-metric]')].map(
                     (r) => [r.dataset.metric, [r.querySelector('td.twin').textContent,
                                                r.querySelector('td.drive').textContent]]))"""
            )
        status, alpha_read = drive_status(url, elf)
    # the drive took the new alpha (float32 of 100 is 100) and ran the whole run
    assert alpha_read == alpha
    assert status["state"] == "done" and status["power_on"] == 0
    t_e, speed_e, ref_e = engine_speed(scenario, alpha)
    step = max(np.ptp(speed_e), np.ptp(ref_e))
    t_d, speed_d = map(np.asarray, plotted["drive speed"])
    t_w, speed_w = map(np.asarray, plotted["twin speed"])
    i_d, i_w = np.searchsorted(t_e, t_d), np.searchsorted(t_e, t_w)
    assert np.array_equal(t_e[i_d], t_d) and np.array_equal(t_e[i_w], t_w)  # plotted points are samples
    drive_error = np.max(np.abs(speed_d - speed_e[i_d])) / step
    twin_error = np.max(np.abs(speed_w - speed_e[i_w])) / step
    t_x, difference = map(np.asarray, plotted["speed difference"])
    print(f"\n  drive vs engine {drive_error:.2e}, twin vs engine {twin_error:.2e} of the step")
    assert drive_error <= AGREEMENT and twin_error <= 1e-12
    assert np.max(np.abs(difference)) <= AGREEMENT * step and len(t_x) > 100
    # the run is the new design's: the old alpha's engine run differs by far more than the bound
    _, speed_old, _ = engine_speed(scenario, 150.0)
    assert np.max(np.abs(speed_old[i_d] - speed_d)) > 100 * AGREEMENT * step
    # the metrics of both: the overshoot of the first step, equal to 1e-4 of it
    twin_pct, drive_pct = (float(x) for x in rows["reference_steps.0.overshoot_pct"])
    assert twin_pct > 0 and drive_pct == pytest.approx(twin_pct, rel=1e-3)


def test_an_unarmed_write_or_run_is_refused_and_writes_nothing(servo, browser):
    scenario, folder = servo
    elf = folder / "virtual_drive_host"
    a2l = folder / "virtual_drive_host.a2l"
    post = """async ([path, body]) => { const r = await fetch(path, {method: 'POST', body: JSON.stringify(body),
                 headers: {'Content-Type': 'application/json', 'X-Pmsm2dof-Client': 'another'}});
                 return [r.status, (await r.json()).error]; }"""
    with serve_host(elf, realtime=False) as url:
        with tuner_on(browser, scenario, url, a2l) as (page, session):
            type_value(page, ALPHA, 90.0)  # the tuner redraws; nothing goes to the disarmed drive
            assert page.evaluate("window.tuner.drive.writes") == 0
            for path in ("api/drive/write", "api/drive/run"):
                status, error = page.evaluate(post, [path, {ALPHA: 90.0}])
                assert status == 409 and "not armed" in error
            # armed by the page, a write of another client is refused too
            arm(page)
            status, error = page.evaluate(post, ["api/drive/write", {ALPHA: 80.0}])
            assert status == 409 and "another page" in error
            # a form of another site cannot post at all (the tuner's rules stay)
            status, error = page.evaluate(
                """async () => { const r = await fetch('api/drive/write', {method: 'POST', body: 'x',
                     headers: {'Content-Type': 'text/plain'}}); return [r.status, (await r.json()).error]; }"""
            )
            assert status == 415
            page.uncheck("#drive-arm")
            page.wait_for_function("!window.tuner.drive.armed")
        status, alpha_read = drive_status(url, elf)
    assert alpha_read == pytest.approx(90.0, rel=1e-7)  # the page's own, written once armed
    assert status["commits_applied"] == 1 and status["state"] == "idle"


def test_a_lost_page_disarms_and_stops_the_drive(servo, browser, capfd):
    """A run of 10 s on the drive on the wall clock: the page's heartbeats keep it armed for longer than the
    timeout; the page closes 4 s into it: HEARTBEAT_TIMEOUT_S after the last heartbeat the server received the
    drive is disarmed, and stopped, power stage off."""
    scenario, folder = servo
    elf = folder / "virtual_drive_host"
    a2l = folder / "virtual_drive_host.a2l"
    with serve_host(elf, realtime=True, timeout_ms=LINK_TIMEOUT_MS) as url:
        with tuner_on(browser, scenario, url, a2l) as (page, session):
            beats = []
            received = session.heartbeat

            def heartbeat(owner):
                armed = received(owner)
                beats.append(time.monotonic())
                return armed

            session.heartbeat = heartbeat  # the app calls the session's: record when each arrives
            type_value(page, "simulation.t_end_s", 10.0)
            arm(page)
            page.click("#drive-run")
            end = time.monotonic() + 10
            while not session.running and time.monotonic() < end:
                time.sleep(0.02)
            time.sleep(HEARTBEAT_TIMEOUT_S + 1.0)
            assert session.armed and session.running
            page.close()
            while session.armed and time.monotonic() < end + 10:
                time.sleep(0.01)
            disarmed = time.monotonic()
            while session.running and time.monotonic() < end + 15:
                time.sleep(0.02)
            silent_s, stopped_s = disarmed - beats[-1], time.monotonic() - disarmed
        status, _ = drive_status(url, elf)
    err = capfd.readouterr().err
    print(f"\n  disarmed {silent_s:.2f} s after the last heartbeat, run stopped {stopped_s:.2f} s later; {err.strip()}")
    assert len(beats) >= HEARTBEAT_TIMEOUT_S  # the page beat every second while it was open
    assert HEARTBEAT_TIMEOUT_S <= silent_s <= HEARTBEAT_TIMEOUT_S + 0.5 and stopped_s < 5.0
    assert status["state"] == "stopped" and status["power_on"] == 0, err
    assert 0 < status["sample"] < 10.0 / 5e-4  # stopped during the run
    assert "no heartbeat from the page" in err and "power stage off" in err


class Proxy:
    """A TCP relay to the drive that the test can cut, as a pulled cable would."""

    def __init__(self, url):
        host, _, port = url[len("socket://") :].rpartition(":")
        self.upstream = (host, int(port))
        self.listener = socket.create_server(("127.0.0.1", 0))
        self.url = f"socket://127.0.0.1:{self.listener.getsockname()[1]}"
        self.sockets = []
        self.dead = False
        self.threads = [threading.Thread(target=self._accept, daemon=True)]
        self.threads[0].start()

    def _accept(self):
        while True:
            try:
                client, _ = self.listener.accept()
            except OSError:
                return
            if self.dead:
                client.close()
                return
            drive = socket.create_connection(self.upstream)
            for s in (client, drive):
                s.setsockopt(socket.IPPROTO_TCP, socket.TCP_NODELAY, 1)
            self.sockets += [client, drive]
            for a, b in ((client, drive), (drive, client)):
                thread = threading.Thread(target=self._pump, args=(a, b), daemon=True)
                self.threads.append(thread)
                thread.start()

    @staticmethod
    def _pump(a, b):
        try:
            while data := a.recv(65536):
                b.sendall(data)
        except OSError:
            pass
        with contextlib.suppress(OSError):
            b.shutdown(socket.SHUT_RDWR)

    def cut(self):
        self.dead = True
        with contextlib.suppress(OSError):
            self.listener.shutdown(socket.SHUT_RDWR)  # wakes the accept
        self.listener.close()
        for s in self.sockets:
            with contextlib.suppress(OSError):
                s.shutdown(socket.SHUT_RDWR)
            s.close()
        for thread in self.threads:
            thread.join(5)


def test_a_link_dropped_during_a_run_is_reported_and_leaves_the_drive_safe(servo, browser, capfd):
    scenario, folder = servo
    elf = folder / "virtual_drive_host"
    a2l = folder / "virtual_drive_host.a2l"
    with serve_host(elf, realtime=True, timeout_ms=LINK_TIMEOUT_MS) as url:
        proxy = Proxy(url)
        try:
            with tuner_on(browser, scenario, proxy.url, a2l) as (page, session):
                type_value(page, "simulation.t_end_s", 4.0)
                arm(page)
                page.click("#drive-run")
                end = time.monotonic() + 10
                while not session.running and time.monotonic() < end:
                    time.sleep(0.02)
                time.sleep(1.5)  # the schedules written, the DAQ set up, the drive running
                proxy.cut()
                cut = time.monotonic()
                page.wait_for_function("window.tuner.drive.alarm", timeout=30000)
                shown = page.locator("#drive-status").inner_text()
        finally:
            proxy.cut()
        # a master that talks to the drive feeds its watchdog: read it once the guard must have stopped it
        time.sleep(max(0.0, cut + LINK_TIMEOUT_MS * 1e-3 + 1.0 - time.monotonic()))
        status, _ = drive_status(url, elf)
    err = capfd.readouterr().err
    print(f"\n  page: {shown}\n  drive: {status['state']}, power {status['power_on']}")
    for text in (shown, err):
        assert "dropped during the run" in text and "watchdog stops it" in text
    # the drive's guard tripped on the silent link: reference ramped down, then power off
    assert status["state"] == "tripped" and status["power_on"] == 0 and status["guard_state"] == 3
    assert 0 < status["trip_sample"] < status["stop_sample"] < 4.0 / 5e-4
