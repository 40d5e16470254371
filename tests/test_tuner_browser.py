"""End to end: the tuner page in a real headless Chromium (Playwright), against a live server.

A person's session: open the page, move the bandwidth slider, see the plotted overshoot and
the metrics table change, pin the run, switch the anti-windup off and see the overshoot grow
(paper section 4.1, Fig. 8), type a bad value and read the message over the dimmed plots,
download the C header and build it with the C core into a program that initializes the
controller. And a drive whose DC link is too low for its speed: the voltage limit is shown.
"""

import contextlib
import math
import shutil
import subprocess
from pathlib import Path

import pytest

from pmsm2dof.sim.scenario import load_scenario
from pmsm2dof.ui.tuner import create_app, serving_in_thread
from pmsm2dof.ui.tuner.experiment import LOG_ROWS_MAX

#: Slow (builds, emulators, fuzzing, browsers or whole reproductions): run by the full suite.
pytestmark = pytest.mark.slow

CHROMIUM = Path("/usr/bin/chromium")
ROOT = Path(__file__).resolve().parents[1]
CHROMIUM_ARGS = [
    "--no-sandbox",
    "--disable-gpu",
    "--disable-background-networking",
    "--disable-component-update",
    "--disable-sync",
    "--no-first-run",
    "--disable-quic",
]

if not CHROMIUM.exists():
    pytest.skip(
        "Debian's chromium is not installed at /usr/bin/chromium (scripts/install.sh installs it)",
        allow_module_level=True,
    )
sync_api = pytest.importorskip("playwright.sync_api", reason="playwright for Python is not installed")

# the plotted speed trace: overshoot [%] of its maximum before the load step over the step
PLOTTED_OVERSHOOT_JS = """() => {
  const run = window.tuner.current;
  const speed = document.getElementById('plot').data.find((d) => d.name === 'speed' && d.xaxis === 'x');
  const step = 500;
  let peak = -Infinity;
  speed.x.forEach((t, i) => { if (t < run.detail.t_s) peak = Math.max(peak, speed.y[i]); });
  return 100 * (peak - step) / step;
}"""
OVERSHOOT = "reference_steps.0.overshoot_pct"
# the traces of the figure: name -> {xaxis, color, dash}
TRACES_JS = """() => Object.fromEntries(document.getElementById('plot').data.map(
  (d) => [d.name, {xaxis: d.xaxis, color: d.line.color, dash: d.line.dash}]))"""


def metric_cells(page, key):
    row = page.locator(f'#metrics tr[data-metric="{key}"]')
    return row.locator("td.current").inner_text(), row.locator("td.pinned").inner_text()


def wait_for_render(page, after):
    """Wait until every change is drawn, with at least one drawing after ``after``."""
    page.wait_for_function(f"!window.tuner.pending && window.tuner.renderCount > {after}", timeout=30000)


@pytest.fixture(scope="module")
def browser():
    with sync_api.sync_playwright() as playwright:
        browser = playwright.chromium.launch(executable_path=str(CHROMIUM), args=CHROMIUM_ARGS)
        yield browser
        browser.close()


@contextlib.contextmanager
def tuner_page(browser, scenario):
    """The tuner of ``scenario`` served and open in a new page, drawn once; no script error."""
    with serving_in_thread(create_app(scenario)) as url:
        page = browser.new_page(viewport={"width": 1440, "height": 900}, accept_downloads=True)
        errors = []
        page.on("pageerror", lambda exc: errors.append(str(exc)))
        page.goto(url)
        wait_for_render(page, 0)
        yield page
        page.close()
        assert not errors, errors


@pytest.fixture(scope="module")
def page(browser):
    with tuner_page(browser, load_scenario("paper-condition-2")) as page:
        yield page


def test_slider_changes_plot_and_table_then_pin_and_compare(page, tmp_path):
    overshoot_before = page.evaluate(PLOTTED_OVERSHOOT_JS)
    table_before, _ = metric_cells(page, OVERSHOOT)
    # alpha = 0.5 rad/s: the first-order tracking of the 2DOF design has no overshoot yet at 7 s
    assert table_before == "\u2013"

    # move the bandwidth slider as a person would, with the keyboard
    renders = page.evaluate("window.tuner.renderCount")
    slider = page.locator('.control[data-key="speed_controller.alpha_radps"] input[type=range]')
    slider.focus()
    for _ in range(150):
        page.keyboard.press("ArrowRight")
    wait_for_render(page, renders)
    alpha = float(page.locator('input[name="speed_controller.alpha_radps"]').input_value())
    assert alpha == pytest.approx(0.5 * 10 ** (150 / 1000 * 2), rel=1e-3)  # log slider over 2 decades
    overshoot_after = page.evaluate(PLOTTED_OVERSHOOT_JS)
    table_after, _ = metric_cells(page, OVERSHOOT)
    assert overshoot_after > 0 > overshoot_before
    assert float(table_after) == pytest.approx(overshoot_after, abs=0.05)
    kp_text = page.locator("#design").inner_text()
    assert f"Kp = {0.4 * alpha:.4g} " in kp_text  # eq 9 with the design inertia 0.4 kg m^2

    # pin, then switch the anti-windup off: the pinned column keeps the run with it
    page.click("#pin")
    page.wait_for_function(
        f"document.querySelector('#metrics tr[data-metric=\"{OVERSHOOT}\"] td.pinned').textContent !== ''"
    )
    assert metric_cells(page, OVERSHOOT)[1] == table_after
    renders = page.evaluate("window.tuner.renderCount")
    page.select_option('select[name="speed_controller.anti_windup"]', "none")
    wait_for_render(page, renders)
    current, pinned = metric_cells(page, OVERSHOOT)
    assert pinned == table_after
    assert float(current) > float(pinned)
    names = page.evaluate("document.getElementById('plot').data.filter((d) => d.xaxis === 'x').map((d) => d.name)")
    assert "speed (pinned)" in names
    traces = page.evaluate(TRACES_JS)

    # the pinned Bode curves: dotted, a colour for Gx and another for GN, none of the current ones
    for unit in ("|Gx| [dB]", "|GN| [dB (rad/s)/Nm]", "\u2220Gx [deg]", "\u2220GN [deg]"):
        assert traces["pinned " + unit]["dash"] == "dot" and traces[unit]["dash"] == "solid"
    colors = [
        traces[name]["color"]
        for name in ("pinned |Gx| [dB]", "pinned |GN| [dB (rad/s)/Nm]", "|Gx| [dB]", "|GN| [dB (rad/s)/Nm]")
    ]
    assert len(set(colors)) == 4
    assert traces["pinned \u2220Gx [deg]"]["color"] == colors[0]
    keys = page.locator("#plot .annotation-text").all_text_contents()
    assert any("pinned Gx" in k and "pinned GN" in k for k in keys)

    # a bad value: a visible message naming the key; the plots stay, dimmed under a banner
    renders = page.evaluate("window.tuner.renderCount")
    assert not page.locator("#stale").is_visible()
    box = page.locator('input[name="speed_controller.zeta"]')
    box.fill("-2")
    box.press("Enter")
    page.wait_for_function("window.tuner.errorCount > 0", timeout=30000)
    banner = page.locator("#error")
    assert banner.is_visible()
    assert "speed_controller.zeta = -2.0 is invalid" in banner.inner_text()
    assert page.locator('.control.invalid[data-key="speed_controller.zeta"]').count() == 1
    assert page.evaluate("window.tuner.renderCount") == renders
    assert page.locator("#stale").is_visible() and page.evaluate("window.tuner.stale")
    assert "last valid settings" in page.locator("#stale").inner_text()
    assert float(page.evaluate("getComputedStyle(document.getElementById('plot')).opacity")) < 0.5
    box.fill("0.2887")
    box.press("Enter")
    wait_for_render(page, renders)
    assert not banner.is_visible()
    assert not page.locator("#stale").is_visible() and not page.evaluate("window.tuner.stale")
    assert page.evaluate("getComputedStyle(document.getElementById('plot')).opacity") == "1"

    page.screenshot(path=str(tmp_path / "tuner.png"))
    assert (tmp_path / "tuner.png").read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"


def test_no_button_sends_the_chart_to_a_cloud_service(page):
    page.locator("#plot").hover()  # the mode bar shows on hover
    titles = page.evaluate("[...document.querySelectorAll('#plot .modebar-btn')].map((b) => b.dataset.title)")
    assert "Download plot as a PNG" in titles
    assert not [t for t in titles if "share" in t.lower() or "cloud" in t.lower() or "chart studio" in t.lower()]
    assert page.evaluate("document.getElementById('plot')._context.showSendToCloud") is False


def test_both_reference_steps_of_the_preset_are_plotted_and_measured(page):
    """paper-condition-2: 500 rpm at 0 s, 8 Nm at 7 s, 200 rpm at 10 s."""
    ref = page.evaluate("""() => {
      const d = document.getElementById('plot').data.find((d) => d.name === 'reference' && d.xaxis === 'x');
      return [d.x, d.y];
    }""")
    levels = {y for t, y in zip(*ref) if 0.01 < t < 9.99} | {y for t, y in zip(*ref) if t > 10.01}
    assert levels == {500.0, 200.0}
    groups = page.locator("#metrics tr.group").all_inner_texts()
    assert groups == [
        "speed reference at 0 s: 0 \u2192 500 rpm",
        "load at 7 s: 0 \u2192 8 Nm",
        "speed reference at 10 s: 500 \u2192 200 rpm",
        "whole run (0 to 15 s)",
    ]
    assert page.locator('#metrics tr[data-metric="reference_steps.1.overshoot_pct"] td.current').inner_text()


def test_the_voltage_and_its_range_are_plotted_without_a_warning_within_it(page):
    traces = page.evaluate(TRACES_JS)
    assert traces["||u_dq||"]["xaxis"] == "x6" and traces["range u_dc/\u221a3"]["xaxis"] == "x6"
    assert metric_cells(page, "run.voltage_limit_time_s")[0] == "0"
    assert not page.locator("#warning").is_visible()
    assert page.locator("#metrics tr.warning").count() == 0


def test_a_drive_at_its_voltage_limit_is_shaded_timed_and_warned_about(browser):
    """u_dc = 60 V: the range u_dc/sqrt(3) = 34.6 V is below the back-EMF of 500 rpm (41.9 V)."""
    with tuner_page(browser, load_scenario("paper-condition-2").with_overrides({"limits.u_dc_V": 60.0})) as page:
        warning = page.locator("#warning")
        assert warning.is_visible() and "Voltage limit" in warning.inner_text()
        row = page.locator('#metrics tr.warning[data-metric="run.voltage_limit_time_s"]')
        assert float(row.locator("td.current").inner_text()) > 3.0
        shapes = page.evaluate("document.getElementById('plot').layout.shapes.map((s) => [s.name, s.xref])")
        assert {xref for name, xref in shapes if name == "voltage limit"} == {"x", "x2", "x3", "x6"}
        keys = page.locator("#plot .annotation-text").all_text_contents()
        assert any("voltage limit" in k for k in keys)


@pytest.mark.skipif(shutil.which("gcc") is None, reason="gcc is not installed")
def test_downloaded_header_builds_and_initializes_the_controllers(page, tmp_path):
    with page.expect_download() as info:
        page.click("#download-header")
    download = info.value
    assert download.suggested_filename == "p2d_config.h"
    download.save_as(tmp_path / "p2d_config.h")
    (tmp_path / "main.c").write_text(
        '#include "p2d_config.h"\n'
        "int main(void)\n{\n"
        "    p2d_speed_t speed;\n    p2d_current_t current;\n    p2d_encoder_t encoder;\n"
        "    if (p2d_speed_init(&speed, &p2d_config_speed) != P2D_OK) return 1;\n"
        "    if (p2d_current_init(&current, &p2d_config_current) != P2D_OK) return 2;\n"
        "    if (p2d_encoder_init(&encoder, &p2d_config_encoder) != P2D_OK) return 3;\n"
        "    if (P2D_CONFIG_FIELD_WEAKENING || P2D_CONFIG_INERTIA) return 4;\n"
        "    if (p2d_config_speed_filter.notch_freq_Hz != 0.0f) return 5;\n"
        "    if (p2d_config_field_weakening.Ts_s != 0.0f || p2d_config_inertia.Ts_s != 0.0f) return 6;\n"
        "    return 0;\n}\n"
    )
    sources = sorted(str(p) for p in (ROOT / "csrc" / "src").glob("*.c"))
    build = subprocess.run(
        [
            "gcc",
            "-std=c99",
            "-Wall",
            "-Wextra",
            "-Wpedantic",
            "-Werror",
            "-I",
            str(ROOT / "csrc" / "include"),
            "-I",
            str(tmp_path),
            str(tmp_path / "main.c"),
            *sources,
            "-lm",
            "-o",
            str(tmp_path / "init"),
        ],
        capture_output=True,
        text=True,
    )
    assert build.returncode == 0, build.stderr
    assert subprocess.run([str(tmp_path / "init")]).returncode == 0


def test_scenario_and_trace_downloads(page, tmp_path):
    with page.expect_download() as info:
        page.click("#download-toml")
    path = tmp_path / info.value.suggested_filename
    info.value.save_as(path)
    scenario = load_scenario(path)
    shown_alpha = float(page.locator('input[name="speed_controller.alpha_radps"]').input_value())
    assert scenario.data["speed_controller"]["alpha_radps"] == shown_alpha
    shown_aw = page.locator('select[name="speed_controller.anti_windup"]').input_value()
    assert scenario.data["speed_controller"]["anti_windup"] == shown_aw

    with page.expect_download() as info:
        page.click("#download-csv")
    lines = Path(info.value.path()).read_text().splitlines()
    assert lines[0].startswith("t_s,")
    t_end = scenario.data["simulation"]["t_end_s"]
    Ts = scenario.data["speed_controller"]["Ts_s"]
    # the run on screen: its samples logged every n-th, n the least that keeps LOG_ROWS_MAX rows
    samples = math.floor(t_end / Ts + 1e-9) + 1
    every = math.ceil(samples / LOG_ROWS_MAX)
    assert len(lines) - 1 == math.ceil(samples / every)
