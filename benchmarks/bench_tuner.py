"""Latency of the tuner: from a control change to redrawn plots, for the paper presets.

Three numbers per preset:

- server: ``Tuner.run`` in-process (design, simulation in the compiled engine, metrics,
  decimation, Bode), of which the simulation alone;
- HTTP: a POST /api/run through uvicorn on loopback, JSON included;
- browser: in headless Chromium, a keyboard step of the alpha slider until the six plots and
  the metrics table are redrawn (``window.tuner.lastLatencyMs``, measured by the page from the
  input event to the animation frame after the redraw; it includes the 10 ms coalescing
  delay), and of it the request (``lastFetchMs``: sent -> JSON parsed).

Every request moves alpha, so no run comes from the tuner's cache. The target is 150 ms.

    python benchmarks/bench_tuner.py [--repeat N] [--screenshot docs/tuner.png]

``--screenshot`` also saves the page comparing the 1DOF PI with back-calculation
anti-windup (pinned) against the same PI without anti-windup (paper Fig. 8).
"""

import argparse
import json
import statistics
import time

import httpx

from pmsm2dof.sim.scenario import list_presets, load_scenario
from pmsm2dof.ui.tuner import create_app, serving_in_thread
from pmsm2dof.ui.tuner.experiment import Tuner

CHROMIUM = "/usr/bin/chromium"
CHROMIUM_ARGS = [
    "--no-sandbox",
    "--disable-gpu",
    "--disable-background-networking",
    "--disable-component-update",
    "--disable-sync",
    "--no-first-run",
    "--disable-quic",
]
PRESETS = [name for name in list_presets() if name.startswith("paper-")]
IDLE = "(n) => !window.tuner.pending && window.tuner.renderCount > n"


def stats(ms):
    ms = sorted(ms)
    return {"median": statistics.median(ms), "p90": ms[int(0.9 * (len(ms) - 1))], "max": ms[-1]}


def bench_server(name, repeat):
    base = load_scenario(name)
    tuner = Tuner(base)
    alpha0 = base.data["speed_controller"]["alpha_radps"]
    tuner.run({})  # warm-up: imports, first allocation
    total, sim, size = [], [], 0
    for k in range(repeat):
        values = {"speed_controller.alpha_radps": alpha0 * (1.0 + 0.003 * (k + 1))}
        out = tuner.run(values)
        total.append(out["server_ms"])
        sim.append(1e3 * tuner._evaluate(values)[1].wall_time_s)
        size = len(json.dumps(out))
    return stats(total), stats(sim), size


def bench_http(url, alpha0, repeat):
    times = []
    with httpx.Client(timeout=30) as client:
        client.post(url + "api/run", json={})
        for k in range(repeat):
            t0 = time.perf_counter()
            response = client.post(
                url + "api/run", json={"speed_controller.alpha_radps": alpha0 * (1.0 - 0.003 * (k + 1))}
            )
            response.raise_for_status()
            times.append(1e3 * (time.perf_counter() - t0))
    return stats(times)


def bench_browser(page, url, repeat):
    page.goto(url)
    page.wait_for_function(IDLE, arg=0, timeout=60000)
    slider = page.locator('.control[data-key="speed_controller.alpha_radps"] input[type=range]')
    latencies, requests = [], []
    for _ in range(repeat):
        renders = page.evaluate("window.tuner.renderCount")
        slider.focus()
        page.keyboard.press("ArrowRight")
        page.wait_for_function(IDLE, arg=renders, timeout=60000)
        latency, request = page.evaluate("[window.tuner.lastLatencyMs, window.tuner.lastFetchMs]")
        latencies.append(latency)
        requests.append(request)
    return stats(requests), stats(latencies)


def select(page, key, value):
    renders = page.evaluate("window.tuner.renderCount")
    page.select_option(f'select[name="{key}"]', value)
    page.wait_for_function(IDLE, arg=renders, timeout=60000)


def screenshot(page, url, path):
    page.goto(url)
    page.wait_for_function(IDLE, arg=0, timeout=60000)
    select(page, "speed_controller.feedforward", "none")
    page.click("#pin")
    select(page, "speed_controller.anti_windup", "none")
    page.screenshot(path=path)


def main():
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--repeat", type=int, default=20)
    parser.add_argument("--screenshot", help="save a screenshot of the page (e.g. docs/tuner.png)")
    args = parser.parse_args()

    from playwright.sync_api import sync_playwright

    rows = []
    with sync_playwright() as playwright:
        browser = playwright.chromium.launch(executable_path=CHROMIUM, args=CHROMIUM_ARGS)
        page = browser.new_page(viewport={"width": 1440, "height": 900})
        for name in PRESETS:
            server, sim, size = bench_server(name, args.repeat)
            base = load_scenario(name)
            with serving_in_thread(create_app(base)) as url:
                http = bench_http(url, base.data["speed_controller"]["alpha_radps"], args.repeat)
                request_ms, browser_ms = bench_browser(page, url, args.repeat)
            rows.append((name, base.data["simulation"]["t_end_s"], sim, server, size, http, request_ms, browser_ms))
            print(
                f"{name}: server {server['median']:.1f} ms (simulation {sim['median']:.1f} ms), "
                f"HTTP {http['median']:.1f} ms, browser {browser_ms['median']:.1f} ms "
                f"(request {request_ms['median']:.1f} ms)",
                flush=True,
            )
        if args.screenshot:
            with serving_in_thread(create_app(load_scenario("paper-condition-2"))) as url:
                screenshot(page, url, args.screenshot)
        browser.close()

    print()
    print(f"median / p90 / max over {args.repeat} changes of alpha [ms]; JSON of one run [kB]")
    print()
    print(
        "| preset | t_end [s] | simulation | server total | JSON | HTTP round trip | browser: request "
        "| browser: change -> redrawn |"
    )
    print("|---|---|---|---|---|---|---|---|")
    for name, t_end, sim, server, size, http, request_ms, browser_ms in rows:
        cells = [f"{s['median']:.0f} / {s['p90']:.0f} / {s['max']:.0f}" for s in (sim, server)]
        cells.append(f"{size / 1024:.0f}")
        cells += [f"{s['median']:.0f} / {s['p90']:.0f} / {s['max']:.0f}" for s in (http, request_ms, browser_ms)]
        print(f"| {name} | {t_end:g} | " + " | ".join(cells) + " |")


if __name__ == "__main__":
    main()
