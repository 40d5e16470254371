"""A drive on the bench: writes of a scenario's speed controller and runs of its steps, with an operator's arming.

:class:`DriveSession` is what a tool that drives a running drive on behalf of a person needs
beside the link (:class:`pmsm2dof.drive.link.Link`): nothing is written and nothing runs unless
the session is armed; an armed session expects a heartbeat from its operator (a page, a
terminal) and, when none comes for ``heartbeat_timeout_s``, disarms and switches the drive's
power stage off (command stop: the drive's safe state, link.h); a link that fails during a write
or a run is reported, and the session reconnects once to stop the drive and read its state. When
the drive cannot be reached at all, the drive's own link watchdog stops it (it ramps the
reference to zero, holds it, then switches the power stage off, after its timeout: docs/mcu.md).

The speed controller reaches the drive as the fields of ``link_speed_config``
(``p2d_speed_config_t``) that a scenario's ``[speed_controller]`` sets (:data:`SPEED_FIELDS`), in
one DOWNLOAD, so that they take effect together at the next speed sample through the
controller's validating, bumpless ``p2d_speed_set_config``. The values are those the firmware
build of the scenario would hold (:func:`pmsm2dof.studies.configuration.configuration`: the same
C init validates them here first). The motor's and the limits' fields stay the drive's.
"""

import dataclasses
import math
import threading
import time
from collections.abc import Callable
from typing import Any

from ..core.bindings import ffi
from ..drive.link import Link
from ..errors import ConfigError, Pmsm2dofError, SimulationError, ToolError
from ..sim.scenario import Scenario
from ..sim.simulate import Result
from .configuration import configuration
from .drive import capture_run, plan_run

#: Fields of p2d_speed_config_t a scenario's [speed_controller] sets, as the tuner's controls do
#: (the speed-loop period Ts_s is the firmware's and is checked, not written).
SPEED_FIELDS = ("alpha_radps", "zeta", "m", "Ka", "method", "feedforward", "anti_windup")
#: Fields of p2d_speed_config_t that are the drive's (motor, limits, current loop): compared with the scenario's.
DRIVE_FIELDS = ("J_kgm2", "tau_i_s", "Ts_s", "i_max_A", "psi_f_Wb", "Ld_H", "Lq_H", "pole_pairs")
#: Fields a tuned scenario of the drive writes (:func:`write_tuned`): the speed controller and the inertia it is
#: designed for (eq 9: the gains follow from alpha, zeta and J together).
TUNED_FIELDS = (*SPEED_FIELDS, "J_kgm2")
#: Longest silence of an armed session's operator before it disarms and stops the drive [s].
HEARTBEAT_TIMEOUT_S = 3.0
#: How often the session's watchdog checks the heartbeat [s].
WATCHDOG_POLL_S = 0.1
#: What the drive does when the link is lost (link.h, docs/mcu.md).
WATCHDOG_SAYS = (
    "its link watchdog stops it after its timeout (reference ramped to zero, held, then the power stage off)"
)
#: Longest run of the drive a session plays, in speed samples (the capture holds every one).
RUN_SAMPLES_MAX = 200_000


class NotArmed(Pmsm2dofError):
    """A write or a run was asked of a session that its operator has not armed."""


class LinkLost(ToolError):
    """The link to the drive failed during a write or a run."""


class RunStopped(ToolError):
    """A run on the drive ended otherwise than done: stopped (the operator lost or disarmed), tripped, or short."""


def speed_config(scenario: Scenario) -> dict[str, Any]:
    """The fields of ``p2d_speed_config_t`` a firmware build of ``scenario`` holds, by field name.

    Enumerations are their integer values; floats are the float32 values the C struct holds.

    Raises
    ------
    ConfigError
        A value the C controllers reject, naming the scenario key.
    """
    cfg = configuration(scenario).engine.cfg.speed
    return {name: getattr(cfg, name) for name, _ in ffi.typeof("p2d_speed_config_t").fields}


def write_speed_controller(
    link: Link, scenario: Scenario, values: dict[str, Any] | None = None, fields: tuple[str, ...] = SPEED_FIELDS
) -> dict[str, Any]:
    """Write the speed controller of ``scenario`` (``fields``, :data:`SPEED_FIELDS`) to the drive in one DOWNLOAD.

    ``values``: :func:`speed_config` of ``scenario`` when already computed. Returns the drive's
    ``link_speed_config`` read back.

    Raises
    ------
    ConfigError
        A value the C controllers reject (nothing written), or another speed-loop period than the drive's.
    ToolError
        The drive rejected the configuration (its error; the drive is unchanged).
    """
    values = speed_config(scenario) if values is None else values
    Ts_s = link.read("link_speed_config.Ts_s")
    if not _same(Ts_s, values["Ts_s"]):
        raise ConfigError(
            "speed_controller.Ts_s",
            scenario.speed_controller.Ts_s,
            f"{Ts_s:g} s, the speed-loop period of the drive's firmware",
        )
    try:
        link.write({f"link_speed_config.{f}": values[f] for f in fields})
    except Pmsm2dofError:
        raise
    except Exception as exc:
        if not _is_xcp_error(exc):
            raise
        st = link.status()
        raise ToolError(
            f"the drive rejected the speed controller ({_text(exc)}, code {st['commit_status']}): "
            "it runs the previous one"
        ) from None
    return {f: link.read(f"link_speed_config.{f}") for f, _ in ffi.typeof("p2d_speed_config_t").fields}


def write_tuned(link: Link, scenario: Scenario) -> dict[str, Any]:
    """Write a tuned scenario of the drive (:data:`TUNED_FIELDS`) in one DOWNLOAD; the drive's values read back.

    ``scenario`` is the drive's configuration with a new speed controller (the ``scenario.toml`` of
    ``pmsm2dof autotune`` of the ``identified.toml`` of ``pmsm2dof drive identify``): its design
    inertia ``speed_controller.J_kgm2`` goes to the drive with alpha, zeta, m, Ka and the forms, so
    that the drive's gains are those autotune chose (eq 9). The scenario's other fields of
    :data:`DRIVE_FIELDS` (motor, limits, loop periods) must be the drive's: they are its hardware's.

    Raises
    ------
    ConfigError
        A value the C controllers reject, or a field of :data:`DRIVE_FIELDS` other than ``J_kgm2`` that
        is not the drive's (nothing written).
    ToolError
        The drive rejected the configuration (its error; the drive is unchanged).
    """
    values = speed_config(scenario)
    for f in DRIVE_FIELDS:
        if f in (*TUNED_FIELDS, "Ts_s"):  # written, or checked by write_speed_controller
            continue
        drive = link.read(f"link_speed_config.{f}")
        if not _same(drive, values[f]):
            raise ConfigError(
                "SCENARIO",
                scenario.name,
                f"a scenario of this drive: its link_speed_config.{f} is {drive!r}, the scenario's {values[f]!r} "
                "(autotune the identified.toml of pmsm2dof drive identify)",
            )
    return write_speed_controller(link, scenario, values, TUNED_FIELDS)


@dataclasses.dataclass
class _Watch:
    """The operator's arming: who armed, and the time of their last heartbeat (time.monotonic)."""

    owner: Any = None
    last_s: float = 0.0


class DriveSession:
    """An operator's session with a drive: armed writes and runs, a heartbeat watchdog, a safe stop.

    Parameters
    ----------
    link : Link
        An open link to the drive (the session closes it).
    scenario : Scenario
        The scenario the drive was built for (its firmware's p2d_config.h).
    heartbeat_timeout_s : float
        Longest silence of an armed operator before the session disarms and stops the drive [s].
    report : callable, optional
        Called with a sentence for every event the operator must hear of (disarmed for want of a
        heartbeat, a link lost, the drive's state after it): a terminal prints it.
    """

    def __init__(
        self,
        link: Link,
        scenario: Scenario,
        *,
        heartbeat_timeout_s: float = HEARTBEAT_TIMEOUT_S,
        report: Callable[[str], None] | None = None,
    ) -> None:
        if not (isinstance(heartbeat_timeout_s, (int, float)) and 0.0 < heartbeat_timeout_s <= 60.0):
            raise ConfigError("heartbeat_timeout_s", heartbeat_timeout_s, "a number of seconds in (0, 60]")
        self.link = link
        self.scenario = scenario
        self.heartbeat_timeout_s = float(heartbeat_timeout_s)
        self.virtual = "vd_trace" in link.variables
        #: How the last run was captured (:class:`pmsm2dof.studies.drive.RunPlan`), None before one.
        self.last_plan: Any = None
        self._report = report
        self._lock = threading.RLock()  # the link: one exchange at a time
        self._watch = _Watch()
        self._state = threading.Lock()  # the arming and the messages
        self._running = False
        self._stop_asked = ""
        self.messages: list[str] = []
        self.lost = ""
        self._closing = threading.Event()
        self._watchdog = threading.Thread(target=self._watch_heartbeat, name="drive-heartbeat", daemon=True)
        self._watchdog.start()

    # ---- arming -------------------------------------------------------------------

    @property
    def armed(self) -> bool:
        """The operator armed the session and is heard from."""
        with self._state:
            return self._watch.owner is not None

    @property
    def running(self) -> bool:
        """A run is being played on the drive."""
        return self._running

    def recent(self) -> list[str]:
        """The latest sentences of :meth:`status`'s ``messages`` (without a read of the drive)."""
        with self._state:
            return list(self.messages)

    def arm(self, owner: Any) -> None:
        """Arm the session for ``owner`` (who must then send heartbeats); reconnects a lost link.

        Raises
        ------
        NotArmed
            Another operator holds the arming.
        LinkLost
            The drive cannot be reached.
        """
        with self._state:
            if self._watch.owner is not None and self._watch.owner != owner:
                raise NotArmed("the drive is armed by another page: disarm it there, or wait until it is lost")
        if self.lost:
            with self._lock:
                try:
                    self.link.open()
                    self.link.status()
                except Exception as exc:
                    raise LinkLost(f"the drive at {self.link.url} cannot be reached: {_text(exc)}") from None
                self.lost = ""
        with self._state:
            self._watch = _Watch(owner, time.monotonic())

    def disarm(self, owner: Any) -> None:
        """Disarm (the owner's wish: nothing is stopped; a run in progress is stopped as when the page is lost)."""
        with self._state:
            if self._watch.owner is not None and self._watch.owner != owner:
                raise NotArmed("the drive is armed by another page")
            self._watch = _Watch()
            if self._running:
                self._stop_asked = "the page disarmed the drive during the run"

    def heartbeat(self, owner: Any) -> bool:
        """The operator ``owner`` is there; returns whether the session is armed for it."""
        with self._state:
            if self._watch.owner is not None and self._watch.owner == owner:
                self._watch.last_s = time.monotonic()
                return True
            return False

    def _require(self, owner: Any) -> None:
        with self._state:
            if self._watch.owner is None:
                raise NotArmed(
                    "the drive is not armed: nothing was written to it (arm it on the page to write to a running drive)"
                )
            if self._watch.owner != owner:
                raise NotArmed("the drive is armed by another page: nothing was written")
        if self.lost:
            raise LinkLost(f"{self.lost}; arm again to reconnect")

    def _watch_heartbeat(self) -> None:
        while not self._closing.wait(WATCHDOG_POLL_S):
            with self._state:
                late = (
                    self._watch.owner is not None and time.monotonic() - self._watch.last_s > self.heartbeat_timeout_s
                )
                if not late:
                    continue
                self._watch = _Watch()
                why = f"no heartbeat from the page for {self.heartbeat_timeout_s:g} s: disarmed"
                running = self._running
                if running:
                    self._stop_asked = why  # the run's poll stops the drive (it holds the link)
            if not running:
                self._say(why + self._stop())

    # ---- the drive ----------------------------------------------------------------

    def _say(self, text: str) -> None:
        with self._state:
            self.messages.append(text)
            del self.messages[:-20]
        if self._report is not None:
            self._report(text)

    def _stop(self) -> str:
        """Stop the drive (power stage off); the end of a sentence: what the drive reports."""
        with self._lock:
            try:
                self.link.stop()
                st = self.link.wait(("stopped", "done", "tripped", "idle"), timeout_s=2.0)
            except Exception as exc:
                self.lost = f"the link to the drive failed ({_text(exc)})"
                return "; the drive cannot be reached: " + WATCHDOG_SAYS
        return f"; the drive is {st['state']}, power stage {'on' if st['power_on'] else 'off'}"

    def status(self) -> dict[str, Any]:
        """What the operator sees: armed, the link's health, the drive's run state and speed controller, messages.

        ``config`` holds the drive's ``p2d_speed_config_t`` read back; ``differs`` the fields of
        :data:`DRIVE_FIELDS` in which it differs from the scenario's build (then the simulation is
        not a twin of this drive).
        """
        with self._state:
            out: dict[str, Any] = {"armed": self._watch.owner is not None, "messages": list(self.messages)}
        out.update(url=self.link.url, virtual=self.virtual, lost=self.lost, running=self._running)
        if self.lost or self._running:
            return out
        with self._lock:
            try:
                drive = self.read_speed_config()
                st = self.link.status()
            except Exception as exc:
                self.lost = f"the link to the drive failed ({_text(exc)})"
                out["lost"] = self.lost
                return out
        built = speed_config(self.scenario)
        out["state"], out["power_on"] = st["state"], bool(st["power_on"])
        out["config"] = drive
        out["differs"] = [f for f in DRIVE_FIELDS if not _same(drive[f], built[f])]
        return out

    def read_speed_config(self) -> dict[str, Any]:
        """The drive's ``link_speed_config``, by field name."""
        with self._lock:
            return {f: self.link.read(f"link_speed_config.{f}") for f, _ in ffi.typeof("p2d_speed_config_t").fields}

    def write(self, scenario: Scenario, owner: Any) -> dict[str, Any]:
        """Write the speed controller of ``scenario`` (:data:`SPEED_FIELDS`) to the drive; its values read back.

        Raises
        ------
        ConfigError
            A value the C controllers reject (nothing written), or another speed-loop period than the drive's.
        NotArmed
            The session is not armed for ``owner`` (nothing written).
        LinkLost
            The link failed (the drive stopped as after a lost link).
        ToolError
            The drive rejected the configuration (its error; the drive is unchanged).
        """
        values = speed_config(scenario)
        self._require(owner)
        with self._lock:
            try:
                return write_speed_controller(self.link, scenario, values)
            except Pmsm2dofError:
                raise
            except Exception as exc:
                raise self._lost_link("a write", exc) from None

    def run(self, scenario: Scenario, owner: Any, *, timeout_s: float = 600.0) -> Result:
        """Write ``scenario``'s speed controller, play its reference and load on the drive; the measured run.

        The run is captured from the firmware's own signals
        (:func:`pmsm2dof.studies.drive.plan_run`, :func:`~pmsm2dof.studies.drive.capture_run`: DAQ or
        the drive's capture buffer, whichever the link and the run's length allow; :attr:`last_plan`
        says which), so any drive with the firmware's variables runs it. While it runs, a lost
        heartbeat or a disarm stops the drive.

        Raises
        ------
        ConfigError
            Bad values (nothing written), a run longer than :data:`RUN_SAMPLES_MAX` samples or than the
            link can capture.
        NotArmed
            The session is not armed for ``owner``.
        LinkLost
            The link failed during the run (the drive stopped or left to its watchdog: the message says which).
        RunStopped
            The run was stopped (the page was lost or disarmed), or ended otherwise than done.
        """
        n = math.floor(scenario.simulation.t_end_s / scenario.speed_controller.Ts_s + 1e-9) + 1
        if n > RUN_SAMPLES_MAX:
            raise ConfigError(
                "simulation.t_end_s",
                scenario.simulation.t_end_s,
                f"<= {RUN_SAMPLES_MAX * scenario.speed_controller.Ts_s:g} s: at most {RUN_SAMPLES_MAX} speed "
                "samples of a run on the drive",
            )
        self.write(scenario, owner)
        stopped: dict[str, str] = {}

        def watch(link: Link, status: dict[str, Any]) -> None:
            with self._state:
                why = self._stop_asked
            if why and not stopped:
                stopped["why"] = why
                link.stop()

        with self._lock:
            with self._state:
                if self._watch.owner is None or self._watch.owner != owner:
                    raise NotArmed("the drive was disarmed before the run started: nothing ran")
                self._running, self._stop_asked = True, ""
            try:
                plan = plan_run(self.link, n)
                self.last_plan = plan
                return capture_run(self.link, scenario, plan, timeout_s=timeout_s, during=watch)
            except SimulationError as exc:
                failure = _text(exc)
            except ToolError as exc:  # the run outlasted timeout_s
                raise RunStopped(f"{exc}{self._stop()}") from None
            except Pmsm2dofError:
                raise
            except Exception as exc:
                raise self._lost_link(f"the run of {n} samples", exc) from None
            finally:
                with self._state:
                    self._running = False
            try:
                st = self.link.status()
            except Exception as exc:
                raise self._lost_link(f"the run of {n} samples", exc) from None
        why = stopped.get("why", "the run on the drive did not end as done")
        text = (
            f"{why}: the drive stopped at sample {st['sample']} of {n} (state {st['state']}, power stage "
            f"{'on' if st['power_on'] else 'off'})" + ("" if stopped else f"; {failure}")
        )
        self._say(text)
        raise RunStopped(text)

    def _lost_link(self, during: str, exc: BaseException) -> LinkLost:
        """After a link failure: reconnect once, stop the drive and read its state; the error that says it all."""
        head = f"the link to the drive at {self.link.url} dropped during {during} ({_text(exc)})"
        try:
            self.link.open()
        except Exception:
            self.lost = head
            text = f"{head}; the drive cannot be reached: {WATCHDOG_SAYS}"
        else:
            self.lost = ""
            text = head + self._stop().replace("; the drive is", "; reconnected and stopped it: the drive is")
        self._say(text)
        return LinkLost(text)

    def close(self) -> None:
        """Stop the watchdog, disarm, stop a drive left running and close the link."""
        self._closing.set()
        self._watchdog.join(2 * WATCHDOG_POLL_S + 1.0)
        with self._state:
            self._watch = _Watch()
        with self._lock:
            self.link.close()


def _same(a: float, b: float) -> bool:
    return bool(a == b or (isinstance(a, float) and isinstance(b, float) and math.isclose(a, b, rel_tol=1e-6)))


def _is_xcp_error(exc: BaseException) -> bool:
    """An error packet of the slave (pyxcp's XcpResponseError): the drive answered and refused."""
    return type(exc).__name__ == "XcpResponseError"


def _text(exc: BaseException) -> str:
    text = str(exc).strip() or type(exc).__name__
    return text if len(text) <= 200 else text[:200] + "..."
