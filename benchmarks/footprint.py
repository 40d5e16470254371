"""Flash, RAM and instructions per step of the controllers on a Cortex-M4F.

Cross-builds ``csrc/`` with ``csrc/cmake/arm-none-eabi-cortex-m4f.cmake`` (the
flags users ship with: ``-mcpu=cortex-m4 -mthumb -mfpu=fpv4-sp-d16
-mfloat-abi=hard -O2 -ffp-contract=off``, plus ``-g``, which changes no code),
then measures:

flash
    ``arm-none-eabi-size`` of each module of the static library, and
    ``arm-none-eabi-nm --size-sort`` of every function. The flash a
    function needs is the sum of the sizes of the functions it can reach: the
    static call graph (``bl``/``b`` targets in the disassembly of the linked
    probe program, newlib's libm included) closed from that function.
RAM
    ``sizeof`` of the structs, as the target compiler lays them out (printed by
    the probe program on the emulator), and the stack one step uses, measured
    on the emulator by painting the free stack before the call and finding the
    lowest word the call overwrote.
instructions per step
    Counted on QEMU (``-M mps2-an386``, a Cortex-M4F) by tracing every executed
    instruction (``-singlestep -d exec,nochain``: one translation block per
    instruction, each logged when it runs). The probe program calls a marker
    before each measured step; the count runs from the step's entry to the
    return address of its call, callees (libm included) counted. These are
    executed instructions, not cycles: on the M4, ``vdiv.f32`` and
    ``vsqrt.f32`` take 14 cycles, loads 2, taken branches 2 to 4 (Cortex-M4
    Technical Reference Manual, instruction timings); QEMU models no cycles.
    The count is checked on ``p2d_speed_Ka_default``, which has no branch: the
    trace must give the number of instructions of its disassembly.

With ``--fixed-point``, writes the section "Fixed-point speed controllers on the Cortex-M0 and M3,
beside float32 on the M4F" only: the float32, Q15 and Q31 speed steps
(``csrc/target/target_fixed_cost.c``) built for each core with its toolchain file and traced on
its QEMU machine (mps2-an386, mps2-an385, microbit), in the same way.

Otherwise writes the sections "Footprint and cost on the Cortex-M4F" (speed and current
controllers, every module), "Footprint of the speed sensing and field weakening
on the Cortex-M4F" (encoder estimators, field weakening, the speed controller's
field-weakening entry), "Inertia estimator on the Cortex-M4F", "Commissioning
routine on the Cortex-M4F" and "Torque filters on the Cortex-M4F" of
``benchmarks/results.md`` (other sections are kept) and prints them. The
commissioning routine is measured over a whole run
(``csrc/target/target_commission_cost.c``): every step is counted, and the
steps are summarised by phase, since a step costs more at the end of an
injection period or of a phase than on an ordinary sample. The torque filters:
the speed step with a notch and a low-pass on its torque command, and
``p2d_filter_step``.
Usage: ``python3 benchmarks/footprint.py [--build-dir DIR] [--fixed-point]``.
"""

import argparse
import os
import re
import subprocess
import sys
import tempfile
from collections import Counter
from pathlib import Path

from results_md import measured_by, write_section

ROOT = Path(__file__).resolve().parents[1]
CSRC = ROOT / "csrc"
TOOLCHAIN = CSRC / "cmake" / "arm-none-eabi-cortex-m4f.cmake"
SECTION = "## Footprint and cost on the Cortex-M4F"
FILTER_SECTION = "## Torque filters on the Cortex-M4F"
INERTIA_SECTION = "## Inertia estimator on the Cortex-M4F"
SENSING_SECTION = "## Footprint of the speed sensing and field weakening on the Cortex-M4F"
# the probes of each section, by controller; the entry of a probe is p2d_<controller>_step unless named here
CONTROLLERS = ("speed", "current")
SENSING_CONTROLLERS = ("encoder", "field_weakening", "speed_fw")
ENTRY = {"speed_fw": "p2d_speed_step_fw"}
QEMU = ["qemu-system-arm", "-M", "mps2-an386", "-nographic", "-semihosting-config", "enable=on,target=native"]
QEMU_TIMEOUT_S = 120
# the configuration with the target: <= 60 instructions per step, <= 1 KiB flash
TARGET = ("speed", "tustin", "back_calculation", "lowpass", "surface")
TARGET_INSTRUCTIONS = 60
TARGET_FLASH_BYTES = 1024


def run(cmd, **kwargs):
    """Run a command, return its stdout; raise with its stderr on failure."""
    done = subprocess.run(cmd, capture_output=True, text=True, **kwargs)
    if done.returncode != 0:
        raise RuntimeError(f"{' '.join(map(str, cmd))} failed ({done.returncode}):\n{done.stderr}")
    return done.stdout


def cross_build(build_dir):
    """Configure and build the library and the probe program for the Cortex-M4F."""
    env = dict(os.environ, CFLAGS="-g")
    run(["cmake", "-S", CSRC, "-B", build_dir, f"-DCMAKE_TOOLCHAIN_FILE={TOOLCHAIN}"], env=env)
    run(
        [
            "cmake",
            "--build",
            build_dir,
            "-j2",
            "--target",
            "pmsm2dof_controller",
            "p2d_target_cost",
            "p2d_commission_cost",
        ]
    )
    return build_dir / "target" / "p2d_target_cost"


def module_sizes(build_dir):
    """{module: (text, data, bss)} of the objects of the static library."""
    objects = sorted((build_dir / "CMakeFiles" / "pmsm2dof_controller.dir" / "src").glob("*.obj"))
    sizes = {}
    for line in run(["arm-none-eabi-size", *objects]).splitlines()[1:]:
        text, data, bss, _, _, path = line.split()
        sizes[Path(path).name.removesuffix(".c.obj")] = (int(text), int(data), int(bss))
    return sizes


def library_functions(build_dir):
    """[(module, symbol, size)] of the static library, largest first (``nm --size-sort``)."""
    out = run(["arm-none-eabi-nm", "--size-sort", "-S", build_dir / "libpmsm2dof_controller.a"])
    rows, module = [], None
    for line in out.splitlines():
        if line.endswith(".obj:"):
            module = line[: -len(".c.obj:")]
        parts = line.split()
        if len(parts) == 4 and parts[2] in "TtRr":
            rows.append((module, parts[3], int(parts[1], 16)))
    return sorted(rows, key=lambda r: -r[2])


def symbols(elf):
    """{function: (address, size)} of the functions in the ELF (thumb bit cleared)."""
    funcs = {}
    for line in run(["arm-none-eabi-nm", "-S", "--defined-only", elf]).splitlines():
        parts = line.split()
        if len(parts) == 4 and parts[2] in "TtWw":
            funcs[parts[3]] = (int(parts[0], 16) & ~1, int(parts[1], 16))
    return funcs


def disassembly(elf):
    """({address: mnemonic}, {function: set of called functions}) of the ELF."""
    mnemonic, calls, current = {}, {}, None
    insn = re.compile(r"^\s*([0-9a-f]+):\s+(\S+)(.*)$")
    for line in run(["arm-none-eabi-objdump", "-d", "--no-show-raw-insn", elf]).splitlines():
        head = re.match(r"^[0-9a-f]+ <(.+)>:$", line)
        if head:
            current = head.group(1)
            calls[current] = set()
            continue
        m = insn.match(line)
        if m and current is not None:
            mnemonic[int(m.group(1), 16)] = m.group(2)
            # a branch to the start of another function is a call or a tail call
            target = re.search(r"<([^>+]+)>", m.group(3))
            if target and m.group(2).startswith(("b", "cb")) and target.group(1) != current:
                calls[current].add(target.group(1))
    return mnemonic, calls


def reachable(calls, root):
    """Functions reachable from root in the static call graph, root included."""
    seen, todo = set(), [root]
    while todo:
        f = todo.pop()
        if f not in seen:
            seen.add(f)
            todo.extend(calls.get(f, ()))
    return seen


def trace(elf, workdir, machine="mps2-an386"):
    """(program output lines, executed PCs in order) of one run of the ELF on QEMU's ``machine``."""
    log = workdir / "exec.log"
    qemu = [QEMU[0], "-M", machine, *QEMU[3:]]
    done = subprocess.run(
        [*qemu, "-singlestep", "-d", "exec,nochain", "-D", log, "-kernel", elf],
        capture_output=True,
        text=True,
        timeout=QEMU_TIMEOUT_S,
        stdin=subprocess.DEVNULL,
    )
    # semihosting output arrives on stderr
    if done.returncode != 0:
        raise RuntimeError(f"probe program failed on QEMU ({done.returncode}):\n{done.stderr[-2000:]}")
    pc = re.compile(r"^Trace \d+: \S+ \[[0-9a-f]+/([0-9a-f]+)/")
    with open(log) as f:
        pcs = [int(m.group(1), 16) for m in map(pc.match, f) if m]
    return done.stderr.splitlines(), pcs


def call_in_trace(pcs, entry, start, mnemonic):
    """(first, end) indices of the first executed call of the function at ``entry`` from index start.

    The call starts at the entry and ends where execution comes back to the
    instruction after its ``bl``.
    """
    first = pcs.index(entry, start)
    call_site = pcs[first - 1]
    if mnemonic.get(call_site) != "bl":
        raise RuntimeError(f"call at {call_site:#x} into {entry:#x} is not a bl")
    return first, pcs.index(call_site + 4, first)


def line_costs(elf, path_pcs):
    """[("file:line", count)] of the executed instructions, most first."""
    out = run(["arm-none-eabi-addr2line", "-e", elf, *(f"{a:#x}" for a in path_pcs)]).splitlines()
    counts = Counter(f"{Path(loc.split(':')[0]).name}:{loc.split(':')[1].split()[0]}" for loc in out)
    return counts.most_common()


def source_line(ref):
    """Text of 'file:line' of the C sources, stripped."""
    name, number = ref.split(":")
    for path in (CSRC / "src" / name, CSRC / "target" / name):
        if path.exists() and number.isdigit():
            return path.read_text().splitlines()[int(number) - 1].strip()
    return "(newlib)"


def function_of(funcs):
    """A function mapping an address to the name of the function that holds it."""
    spans = sorted((a, a + s, n) for n, (a, s) in funcs.items() if s > 0)

    def name(addr):
        for lo, hi, n in spans:
            if lo <= addr < hi:
                return n
        return "?"

    return name


def measure(build_dir, workdir):
    """Every number of the report, from a cross build in build_dir and a QEMU trace in workdir."""
    elf = cross_build(build_dir)
    funcs = symbols(elf)
    mnemonic, calls = disassembly(elf)
    lines, pcs = trace(elf, workdir)

    sizeof = {p[1]: int(p[2], 16) for p in (ln.split() for ln in lines) if p and p[0] == "sizeof"}
    probes = [ln.split() for ln in lines if ln.startswith("probe ")]
    filter_probes = [ln.split() for ln in lines if ln.startswith("filter_probe ")]
    if not lines or lines[-1] != "END":
        raise RuntimeError("probe program did not finish:\n" + "\n".join(lines[-5:]))

    # check of the counting method on a function without branches
    ka = funcs["p2d_speed_Ka_default"]
    ka_disassembled = sum(1 for a in mnemonic if ka[0] <= a < ka[0] + ka[1] and not mnemonic[a].startswith("."))
    first, end = call_in_trace(pcs, ka[0], 0, mnemonic)
    if end - first != ka_disassembled:
        raise RuntimeError(
            f"trace counts {end - first} instructions in p2d_speed_Ka_default, its disassembly has {ka_disassembled}"
        )

    marks = [i for i, a in enumerate(pcs) if a == funcs["p2d_cost_mark"][0]]
    where = function_of(funcs)
    rows = []
    for probe in probes:
        # probe <index> <controller> <description...> <point> stack <bytes>
        index = int(probe[1], 16)
        controller = probe[2]
        entry = funcs[ENTRY.get(controller, f"p2d_{controller}_step")][0]
        first, end = call_in_trace(pcs, entry, marks[index], mnemonic)
        path = pcs[first:end]
        rows.append(
            dict(
                key=tuple(probe[2:-3]),
                point=probe[-3],
                stack=int(probe[-1], 16),
                count=len(path),
                divides=sum(mnemonic[a] in ("vdiv.f32", "vsqrt.f32") for a in path),
                per_function=Counter(where(a) for a in path),
                path=path,
            )
        )

    filter_rows = []
    for probe in filter_probes:
        # filter_probe <index> <speed|filter> <sections> <motor> <point> stack <bytes>
        index, controller = int(probe[1], 16), probe[2]
        entry = funcs[f"p2d_{controller}_step"][0]
        first, end = call_in_trace(pcs, entry, marks[index], mnemonic)
        path = pcs[first:end]
        filter_rows.append(
            dict(
                controller=controller,
                sections=probe[3],
                motor=probe[4],
                point=probe[5],
                stack=int(probe[7], 16),
                count=len(path),
                divides=sum(mnemonic[a] in ("vdiv.f32", "vsqrt.f32") for a in path),
            )
        )

    def flash_of(names):
        names = sorted(f for f in names if f in funcs)
        return sum(funcs[f][1] for f in names), names

    flash = {
        root: flash_of(reachable(calls, root))
        for root in (
            "p2d_speed_step",
            "p2d_speed_init",
            "p2d_current_step",
            "p2d_current_init",
            "p2d_inertia_step",
            "p2d_inertia_init",
            "p2d_speed_step_fw",
            "p2d_encoder_step",
            "p2d_encoder_init",
            "p2d_field_weakening_step",
            "p2d_field_weakening_init",
        )
    }
    for controller in ("speed", "current", "encoder", "field_weakening"):
        entries = [f for f in funcs if f.startswith(f"p2d_{controller}_")]
        flash[f"{controller} controller (all p2d_{controller}_*)"] = flash_of(
            set().union(*(reachable(calls, f) for f in entries))
        )
    entries = [f for f in funcs if f.startswith("p2d_inertia_")]
    flash["inertia estimator (all p2d_inertia_*)"] = flash_of(set().union(*(reachable(calls, f) for f in entries)))

    filter_flash = {
        root: flash_of(reachable(calls, root))
        for root in ("p2d_filter_step", "p2d_filter_init", "p2d_speed_set_filter")
    }
    target_rows = [r for r in rows if r["key"] == TARGET]
    hot = line_costs(elf, [a for r in target_rows if r["point"] == "unsaturated" for a in r["path"]])
    inertia_update = [r for r in rows if r["key"] == ("inertia", "sampled") and r["point"] == "update"]
    inertia_hot = line_costs(elf, inertia_update[0]["path"])
    return dict(
        modules=module_sizes(build_dir),
        library=library_functions(build_dir),
        funcs=funcs,
        sizeof=sizeof,
        rows=rows,
        flash=flash,
        hot=hot,
        inertia_hot=inertia_hot,
        ka_check=ka_disassembled,
        filter_rows=filter_rows,
        filter_flash=filter_flash,
    )


def tool_version(cmd):
    return run([cmd, "--version"]).splitlines()[0]


def code_version():
    """Commit of the measured sources, and whether they differed from it."""
    sources = ["csrc/src", "csrc/include", "csrc/target"]
    commit = run(["git", "-C", ROOT, "rev-parse", "--short", "HEAD"]).strip()
    dirty = run(["git", "-C", ROOT, "status", "--porcelain", "--", *sources]).strip()
    return f"commit {commit}" + (f" with uncommitted changes in {', '.join(sources)}" if dirty else "")


def report(m):
    """The markdown section of the results."""
    out = [
        SECTION,
        "",
        measured_by("python3 benchmarks/footprint.py") + ";",
        f"{tool_version('arm-none-eabi-gcc')}; {tool_version('qemu-system-arm')}; code: {code_version()}.",
        "Flags: `-mcpu=cortex-m4 -mthumb -mfpu=fpv4-sp-d16 -mfloat-abi=hard -O2 -ffp-contract=off`, newlib-nano.",
        "",
        "### Flash and RAM of the library modules (`arm-none-eabi-size`, bytes)",
        "",
        "| module | text (flash) | data | bss |",
        "|---|---:|---:|---:|",
    ]
    for name, (text, data, bss) in m["modules"].items():
        out.append(f"| {name}.c | {text} | {data} | {bss} |")
    out += [
        "",
        "Text includes read-only data (the status strings of status.c). No module has .data or .bss:",
        "the controllers keep all state in the structs the caller allocates.",
        "",
        "### Per function (`arm-none-eabi-nm --size-sort`, bytes)",
        "",
        "| module | symbol | size |",
        "|---|---|---:|",
    ]
    out += [f"| {mod}.c | {sym} | {size} |" for mod, sym, size in m["library"]]
    out += [
        "",
        "### Flash reachable from an entry point (static call graph, newlib included, bytes)",
        "",
        "| entry | flash | functions |",
        "|---|---:|---|",
    ]
    for root, (size, reach) in m["flash"].items():
        if not is_sensing(root) and "inertia" not in root:
            out.append(f"| {root} | {size} | " + ", ".join(f"{f} {m['funcs'][f][1]}" for f in reach) + " |")
    out += ["", "### RAM", "", "| struct | sizeof (bytes) |", "|---|---:|"]
    out += [f"| {t} | {s} |" for t, s in m["sizeof"].items() if not is_sensing(t) and not t.startswith("p2d_inertia")]
    rows = [r for r in m["rows"] if r["key"][0] in CONTROLLERS]
    stack = {}
    for r in rows:
        stack[r["key"][0]] = max(stack.get(r["key"][0], 0), r["stack"])
    out += [
        "",
        "Stack of one step, largest over the probes (measured, painted stack): "
        + ", ".join(f"{k} {b} bytes" for k, b in stack.items())
        + ".",
        "The firmware holds one `p2d_speed_t` and one `p2d_current_t` (static); the outputs live on the stack.",
        "",
        "### Instructions executed by one step (QEMU trace; callees included)",
        "",
        f"Counting method checked: the trace of `p2d_speed_Ka_default` has {m['ka_check']} instructions, "
        "as many as its disassembly.",
        "",
        "| controller | method | anti-windup | feedforward / decoupling | motor | unsaturated | saturated "
        "| vdiv+vsqrt (unsat/sat) |",
        "|---|---|---|---|---|---:|---:|---:|",
    ]
    by_key = {}
    for r in rows:
        by_key.setdefault(r["key"], {})[r["point"]] = r
    for key, points in by_key.items():
        unsat, sat = points.get("unsaturated"), points.get("saturated")
        cell = lambda r, f: str(r[f]) if r else "-"  # noqa: E731
        out.append(
            f"| {' | '.join(key)} | {cell(unsat, 'count')} | {cell(sat, 'count')} | "
            f"{cell(unsat, 'divides')}/{cell(sat, 'divides')} |"
        )
    target = by_key[TARGET]
    worst = max(r["count"] for r in target.values())
    step_flash = m["flash"]["p2d_speed_step"][0]
    out += [
        "",
        "### Target: Tustin, back calculation, lowpass feedforward (surface PMSM)",
        "",
        f"- instructions per speed step: {target['unsaturated']['count']} unsaturated, "
        f"{target['saturated']['count']} saturated; target <= {TARGET_INSTRUCTIONS}: "
        + ("met" if worst <= TARGET_INSTRUCTIONS else f"missed by {worst - TARGET_INSTRUCTIONS}"),
        f"- flash reachable from `p2d_speed_step`: {step_flash} bytes; target <= {TARGET_FLASH_BYTES}: "
        + ("met" if step_flash <= TARGET_FLASH_BYTES else f"missed by {step_flash - TARGET_FLASH_BYTES}"),
        "- where the unsaturated step spends its instructions, by function: "
        + ", ".join(f"{f} {n}" for f, n in target["unsaturated"]["per_function"].most_common()),
        "",
        "Instructions by source line (unsaturated step):",
        "",
        "| instructions | line | source |",
        "|---:|---|---|",
    ]
    out += [f"| {n} | {ref} | `{source_line(ref)}` |" for ref, n in m["hot"]]
    return "\n".join(out) + "\n"


COMMISSION_SECTION = "## Commissioning routine on the Cortex-M4F"


def commission_measure(build_dir, workdir):
    """Instructions of every step of one commissioning, by phase; flash, RAM and stack of the routine."""
    elf = build_dir / "target" / "p2d_commission_cost"
    funcs = symbols(elf)
    mnemonic, calls = disassembly(elf)
    lines, pcs = trace(elf, workdir)
    if not lines or lines[-1] != "END":
        raise RuntimeError("commissioning probe did not finish:\n" + "\n".join(lines[-5:]))
    fields = [ln.split() for ln in lines]
    sizeof = {p[1]: int(p[2], 16) for p in fields if p and p[0] == "sizeof"}
    stack = next(int(p[1], 16) for p in fields if p and p[0] == "stack")
    steps = [(int(p[1], 16), int(p[2], 16)) for p in fields if p and p[0] == "cstep"]
    marks = [i for i, a in enumerate(pcs) if a == funcs["p2d_cost_mark"][0]]
    if len(marks) != len(steps):
        raise RuntimeError(f"{len(marks)} marks in the trace for {len(steps)} steps")
    entry, where = funcs["p2d_commission_step"][0], function_of(funcs)
    by_phase = {}
    for index, phase in steps:
        first, end = call_in_trace(pcs, entry, marks[index], mnemonic)
        path = pcs[first:end]
        by_phase.setdefault(phase, []).append(
            dict(
                index=index,
                count=len(path),
                divides=sum(mnemonic[a] in ("vdiv.f32", "vsqrt.f32") for a in path),
                per_function=Counter(where(a) for a in path),
            )
        )

    def flash_of(roots):
        names = sorted(f for f in set().union(*(reachable(calls, r) for r in roots)) if f in funcs)
        return sum(funcs[f][1] for f in names), names

    entries = sorted(f for f in funcs if f.startswith("p2d_commission_"))
    flash = {
        "p2d_commission_step": flash_of(["p2d_commission_step"]),
        "p2d_commission_init": flash_of(["p2d_commission_init"]),
        "the routine (all p2d_commission_*)": flash_of(entries),
    }
    result = next(p[1:] for p in fields if p and p[0] == "result")
    return dict(
        by_phase=by_phase,
        flash=flash,
        funcs=funcs,
        sizeof=sizeof,
        stack=stack,
        steps=len(steps),
        result=result,
        module=module_sizes(build_dir).get("commission"),
    )


PHASE_NAMES = ("probe", "align", "rs_low", "rs_high", "ld", "lq", "ramp_up", "spin", "ramp_down")


def commission_report(m):
    """The markdown section of the commissioning routine."""
    out = [
        COMMISSION_SECTION,
        "",
        measured_by("python3 benchmarks/footprint.py") + ";",
        f"{tool_version('arm-none-eabi-gcc')}; {tool_version('qemu-system-arm')}; code: {code_version()}.",
        "Flags: `-mcpu=cortex-m4 -mthumb -mfpu=fpv4-sp-d16 -mfloat-abi=hard -O2 -ffp-contract=off`, newlib-nano.",
        "",
        f"One whole commissioning traced on QEMU (`csrc/target/target_commission_cost.c`: a small servo, 100 us "
        f"samples, the motor emulated in float32 on the target; it ended in phase {int(m['result'][0], 16)}, "
        f"{'DONE' if int(m['result'][0], 16) == 9 else 'not DONE'}): {m['steps']} steps, each counted from the entry "
        "of `p2d_commission_step` to its return, callees included (executed instructions, not cycles; see the "
        "previous section).",
        "",
        "| phase | steps | instructions per step: median | max | vdiv+vsqrt (max step) | the max step spends most in |",
        "|---|---:|---:|---:|---:|---|",
    ]
    worst = None
    for phase, name in enumerate(PHASE_NAMES):
        rows = m["by_phase"].get(phase, [])
        if not rows:
            out.append(f"| {name} | 0 | - | - | - | - |")
            continue
        counts = sorted(r["count"] for r in rows)
        top = max(rows, key=lambda r: r["count"])
        if worst is None or top["count"] > worst[1]["count"]:
            worst = (name, top)
        spends = ", ".join(f"{f} {n}" for f, n in top["per_function"].most_common(3))
        out.append(
            f"| {name} | {len(rows)} | {counts[len(counts) // 2]} | {top['count']} | {top['divides']} | {spends} |"
        )
    name, top = worst
    flash_step = m["flash"]["p2d_commission_step"][0]
    out += [
        "",
        f"- the most expensive step: {top['count']} instructions ({name}, step {top['index']}; the steps that end "
        "a phase compute its estimates and design the next current loop);",
        f"- flash reachable from `p2d_commission_step`: {flash_step} bytes; from `p2d_commission_init`: "
        f"{m['flash']['p2d_commission_init'][0]} bytes; the whole routine, names and texts included: "
        f"{m['flash']['the routine (all p2d_commission_*)'][0]} bytes (static call graph, newlib included)"
        + (f"; `commission.c` alone: {m['module'][0]} bytes of text, no data or bss;" if m["module"] else ";"),
        "- RAM: "
        + ", ".join(f"`{t}` {s} bytes" for t, s in m["sizeof"].items())
        + f"; stack of a step: {m['stack']} bytes (painted stack, largest over the run).",
        "",
        "Functions reachable from `p2d_commission_step` (bytes): "
        + ", ".join(f"{f} {m['funcs'][f][1]}" for f in m["flash"]["p2d_commission_step"][1])
        + ".",
    ]
    return "\n".join(out) + "\n"


def is_sensing(name):
    """Whether a struct, entry or flash row belongs to the speed sensing and field weakening section."""
    return any(k in name for k in ("encoder", "field_weakening", "_fw"))


def report_sensing(m):
    """The markdown section of the speed sensing and field weakening."""
    out = [
        SENSING_SECTION,
        "",
        measured_by("python3 benchmarks/footprint.py") + " (the same build and trace as the section above).",
        "",
        "Encoder: 10000 counts/rev on a 16-bit timer read at 1 kHz, a step across the timer's wrap "
        "(csrc/include/pmsm2dof/encoder.h). Field weakening: 10 kHz on a 48 V link, Tustin "
        "(csrc/include/pmsm2dof/field_weakening.h). `p2d_speed_step_fw`: the speed step of the table above "
        "(Tustin, back calculation, lowpass feedforward) with id_fw = -4 A of 7.6 A.",
        "",
        "### Instructions executed by one step (QEMU trace; callees included)",
        "",
        "| entry | configuration | point | instructions | vdiv+vsqrt | stack (bytes) |",
        "|---|---|---|---:|---:|---:|",
    ]
    for r in m["rows"]:
        controller = r["key"][0]
        if controller not in SENSING_CONTROLLERS:
            continue
        config = " ".join(k for k in r["key"][1:] if k != "-")
        out.append(
            f"| `{ENTRY.get(controller, f'p2d_{controller}_step')}` | {config} | {r['point']} | {r['count']} "
            f"| {r['divides']} | {r['stack']} |"
        )
    plain = {r["point"]: r["count"] for r in m["rows"] if r["key"] == TARGET}
    fw = {r["point"]: r["count"] for r in m["rows"] if r["key"] == ("speed_fw", *TARGET[1:])}
    out += [
        "",
        f"The field-weakening entry costs {fw['unsaturated'] - plain['unsaturated']} (unsaturated) and "
        f"{fw['saturated'] - plain['saturated']} (saturated) instructions more than `p2d_speed_step` "
        f"({plain['unsaturated']} / {plain['saturated']}, unchanged): the q current that remains, a square root, "
        "the compute/update split and the tests of the torque filters (the entry runs them when configured).",
        "",
        "### Flash reachable from an entry point (static call graph, newlib included, bytes)",
        "",
        "| entry | flash | functions |",
        "|---|---:|---|",
    ]
    for root, (size, reach) in m["flash"].items():
        if is_sensing(root):
            out.append(f"| {root} | {size} | " + ", ".join(f"{f} {m['funcs'][f][1]}" for f in reach) + " |")
    out += ["", "### RAM", "", "| struct | sizeof (bytes) |", "|---|---:|"]
    out += [f"| {t} | {s} |" for t, s in m["sizeof"].items() if is_sensing(t)]
    return "\n".join(out) + "\n"


def inertia_report(m):
    """The markdown section of the inertia estimator (csrc/include/pmsm2dof/inertia.h)."""
    text, data, bss = m["modules"]["inertia"]
    out = [
        INERTIA_SECTION,
        "",
        measured_by("python3 benchmarks/footprint.py") + ", with the controllers' section above;",
        f"same toolchain, flags and code ({code_version()}). The estimator runs once per speed sample: at 1 kHz "
        "on a 168 MHz Cortex-M4F, 1000 instructions would be about 0.6 % of the core.",
        "",
        f"`inertia.c`: {text} bytes of flash, {data} of .data, {bss} of .bss.",
        "",
        "| symbol | size (bytes) |",
        "|---|---:|",
    ]
    out += [f"| {sym} | {size} |" for mod, sym, size in m["library"] if mod == "inertia"]
    out += [
        "",
        "Flash reachable from an entry point (static call graph, newlib included):",
        "",
        "| entry | flash (bytes) | functions |",
        "|---|---:|---|",
    ]
    for root, (size, reach) in m["flash"].items():
        if "inertia" in root:
            out.append(f"| {root} | {size} | " + ", ".join(f"{f} {m['funcs'][f][1]}" for f in reach) + " |")
    out += ["", "| struct | sizeof (bytes) |", "|---|---:|"]
    out += [f"| {t} | {s} |" for t, s in m["sizeof"].items() if t.startswith("p2d_inertia")]
    out += [
        "",
        "Instructions executed by one `p2d_inertia_step` (QEMU trace, callees included) and the stack it "
        "used (painted stack):",
        "",
        "| speed input | point | instructions | vdiv+vsqrt | stack (bytes) |",
        "|---|---|---:|---:|---:|",
    ]
    points = {
        "start": "prefilter start (first sample)",
        "prior": "first update (J at its prior variance)",
        "update": "update (forgetting)",
        "fault": "NaN speed (fault)",
    }
    for r in m["rows"]:
        if r["key"][0] == "inertia":
            out.append(f"| {r['key'][1]} | {points[r['point']]} | {r['count']} | {r['divides']} | {r['stack']} |")
    out += [
        "",
        "Instructions by source line (update, sampled speed), the 25 costliest lines:",
        "",
        "| instructions | line | source |",
        "|---:|---|---|",
    ]
    out += [f"| {n} | {ref} | `{source_line(ref)}` |" for ref, n in m["inertia_hot"][:25]]
    return "\n".join(out) + "\n"


def filter_report(m):
    """The markdown section of the torque filters (filter.h and p2d_speed_set_filter)."""
    plain = {r["point"]: r["count"] for r in m["rows"] if r["key"] == TARGET}
    out = [
        FILTER_SECTION,
        "",
        measured_by("python3 benchmarks/footprint.py") + ";",
        f"{tool_version('arm-none-eabi-gcc')}; {tool_version('qemu-system-arm')}; code: {code_version()}.",
        "Flags as in the section above. Filters of a 40 Hz resonance at the 1 kHz speed loop: a notch (40 Hz, "
        "15 Hz wide, depth 0.05) and a low-pass (200 Hz, zeta 0.707); the speed controller is the target "
        "configuration (Tustin, back calculation, lowpass feedforward).",
        "",
        "### Instructions executed by one step (QEMU trace; callees included)",
        "",
        f"Without filters the speed step is the one above: {plain.get('unsaturated', '-')} unsaturated, "
        f"{plain.get('saturated', '-')} saturated (surface PMSM).",
        "",
        "| step | filters | motor | point | instructions | vdiv+vsqrt | stack (bytes) |",
        "|---|---|---|---|---:|---:|---:|",
    ]
    for r in m["filter_rows"]:
        step = "p2d_speed_step" if r["controller"] == "speed" else "p2d_filter_step"
        out.append(
            f"| {step} | {r['sections']} | {r['motor']} | {r['point']} | {r['count']} | {r['divides']} | {r['stack']} |"
        )
    out += [
        "",
        "The speed step leaves its surface-PMSM path after u for the filtered one (a tail call): the "
        "filters, the limit on the filtered command, the current and the update with u* = u_sat - u_f.",
        "",
        "### Flash reachable from an entry point (static call graph, newlib included, bytes)",
        "",
        "| entry | flash | functions |",
        "|---|---:|---|",
    ]
    for root, (size, reach) in m["filter_flash"].items():
        out.append(f"| {root} | {size} | " + ", ".join(f"{f} {m['funcs'][f][1]}" for f in reach) + " |")
    out += ["", "### RAM", "", "| struct | sizeof (bytes) |", "|---|---:|"]
    out += [f"| {t} | {b} |" for t, b in m["sizeof"].items() if t.startswith("p2d_filter") or t == "p2d_speed_t"]
    out += [
        "",
        "`p2d_speed_t` holds the torque filters' two coefficient sets, configuration and state "
        "(`p2d_filter_coef_t` twice, `p2d_filter_config_t`, `p2d_filter_state_t`), used or not.",
    ]
    return "\n".join(out) + "\n"


FIXED_SECTION = "## Fixed-point speed controllers on the Cortex-M0 and M3, beside float32 on the M4F"
#: core: (toolchain file, QEMU machine, board)
FIXED_CORES = {
    "Cortex-M4F": ("arm-none-eabi-cortex-m4f.cmake", "mps2-an386"),
    "Cortex-M3": ("arm-none-eabi-cortex-m3.cmake", "mps2-an385"),
    "Cortex-M0": ("arm-none-eabi-cortex-m0.cmake", "microbit"),
}
FIXED_CONTROLLERS = {"speed": "float32", "speed_q15": "Q15", "speed_q31": "Q31"}


def _flash(funcs, calls, root):
    """(bytes, names) of the functions reachable from root (static call graph)."""
    names = sorted(f for f in reachable(calls, root) if f in funcs)
    return sum(funcs[f][1] for f in names), names


def fixed_measure(workdir):
    """Instructions, stack and flash of the float32, Q15 and Q31 speed steps on every core
    (``csrc/target/target_fixed_cost.c``, each core's cross build and QEMU machine)."""
    cores = {}
    for core, (toolchain, machine) in FIXED_CORES.items():
        build = workdir / f"build-{machine}"
        env = dict(os.environ, CFLAGS="-g")
        run(["cmake", "-S", CSRC, "-B", build, f"-DCMAKE_TOOLCHAIN_FILE={CSRC / 'cmake' / toolchain}"], env=env)
        run(["cmake", "--build", build, "-j2", "--target", "p2d_fixed_cost"])
        elf = build / "target" / "p2d_fixed_cost"
        funcs = symbols(elf)
        mnemonic, calls = disassembly(elf)
        lines, pcs = trace(elf, workdir, machine)
        if not lines or lines[-1] != "END":
            raise RuntimeError(f"{core}: probe program did not finish:\n" + "\n".join(lines[-5:]))
        # the counting method, on a function without branches
        start, size = funcs["p2d_cost_mark"]
        disassembled = sum(1 for a in mnemonic if start <= a < start + size and not mnemonic[a].startswith("."))
        first, end = call_in_trace(pcs, start, 0, mnemonic)
        if end - first != disassembled:
            raise RuntimeError(f"{core}: {end - first} instructions of p2d_cost_mark traced, {disassembled} in it")
        marks = [i for i, a in enumerate(pcs) if a == funcs["p2d_cost_mark"][0]]
        probes = {}
        for p in (ln.split() for ln in lines if ln.startswith("probe ")):
            # probe <index> <controller> <point> stack <bytes>
            controller, point = p[2], p[3]
            first, end = call_in_trace(pcs, funcs[f"p2d_{controller}_step"][0], marks[int(p[1], 16)], mnemonic)
            probes[(controller, point)] = (end - first, int(p[5], 16))
        cores[core] = dict(
            machine=machine,
            probes=probes,
            sizeof={p[1]: int(p[2], 16) for p in (ln.split() for ln in lines) if p and p[0] == "sizeof"},
            step_flash={c: _flash(funcs, calls, f"p2d_{c}_step") for c in FIXED_CONTROLLERS},
            init_flash={c: _flash(funcs, calls, f"p2d_{c}_init") for c in FIXED_CONTROLLERS},
            check=disassembled,
        )
    return cores


def fixed_report(cores):
    """The markdown section of the fixed-point controllers."""
    out = [
        FIXED_SECTION,
        "",
        measured_by("python3 benchmarks/footprint.py --fixed-point") + ";",
        f"{tool_version('arm-none-eabi-gcc')}; {tool_version('qemu-system-arm')}; code: {code_version()}.",
        "Flags: `-mthumb -O2 -ffp-contract=off`, newlib-nano, with `-mcpu=cortex-m4 -mfpu=fpv4-sp-d16 "
        "-mfloat-abi=hard` (M4F, QEMU mps2-an386), `-mcpu=cortex-m3 -mfloat-abi=soft` (M3, mps2-an385), "
        "`-mcpu=cortex-m0 -mfloat-abi=soft` (M0, microbit).",
        "",
        "One step of the speed controller (`csrc/target/target_fixed_cost.c`: the paper's drive, Tustin, back "
        "calculation, lowpass feedforward, surface PMSM; fixed point scaled to 1000 rpm and 32 Nm), counted on "
        "QEMU from the step's entry to its return, callees included (executed instructions, not cycles: on the "
        "M0 a `muls` takes 1 or 32 cycles by the core's build option, on the M3 a taken branch 2 to 4). Without an "
        "FPU the float32 step runs on the compiler's software floating point. The counting method is checked on "
        "each core: the trace of `p2d_cost_mark` has as many instructions as its disassembly ("
        + ", ".join(f"{c['check']} on the {k}" for k, c in cores.items())
        + "). Init validates the design by the float controller's rules (`p2d_speed_init`) and computes the "
        "coefficients in double, on a core without an FPU with the compiler's software floating point: hence its "
        "flash.",
        "",
        "| core | controller | instructions per step: unsaturated | saturated | stack (bytes) "
        "| flash reachable from the step (bytes) | from init (bytes) |",
        "|---|---|---:|---:|---:|---:|---:|",
    ]
    for core, c in cores.items():
        for controller, name in FIXED_CONTROLLERS.items():
            unsat, sat = c["probes"][(controller, "unsaturated")], c["probes"][(controller, "saturated")]
            out.append(
                f"| {core} | {name} | {unsat[0]} | {sat[0]} | {max(unsat[1], sat[1])} | "
                f"{c['step_flash'][controller][0]} | {c['init_flash'][controller][0]} |"
            )
    out += ["", "RAM (`sizeof`, the same on every core):", ""]
    sizes = next(iter(cores.values()))["sizeof"]
    out += [", ".join(f"`{t}` {s}" for t, s in sizes.items()) + " bytes."]
    out += ["", "Functions reachable from each fixed-point step (bytes):", ""]
    for core, c in cores.items():
        for controller in ("speed_q15", "speed_q31"):
            size, names = c["step_flash"][controller]
            out.append(f"- {core}, `p2d_{controller}_step` ({size}): " + ", ".join(names))
    return "\n".join(out) + "\n"


def main(argv=None):
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--build-dir", type=Path, help="cross build directory (default: a temporary one)")
    parser.add_argument(
        "--fixed-point",
        action="store_true",
        help=f"measure the section {FIXED_SECTION[3:]!r} only (three cross builds, one for each core)",
    )
    args = parser.parse_args(argv)
    if args.fixed_point:
        with tempfile.TemporaryDirectory(prefix="p2d-footprint-") as tmp:
            text = fixed_report(fixed_measure(Path(tmp)))
        write_section(FIXED_SECTION, text)
        print(text)
        return 0
    with tempfile.TemporaryDirectory(prefix="p2d-footprint-") as tmp:
        build_dir = (args.build_dir or Path(tmp) / "build").resolve()
        measured = measure(build_dir, Path(tmp))
        commission_text = commission_report(commission_measure(build_dir, Path(tmp)))
    text, sensing, inertia_text = report(measured), report_sensing(measured), inertia_report(measured)
    filters = filter_report(measured)
    write_section(SECTION, text)
    write_section(SENSING_SECTION, sensing)
    write_section(INERTIA_SECTION, inertia_text)
    write_section(COMMISSION_SECTION, commission_text)
    write_section(FILTER_SECTION, filters)
    print(text + "\n" + sensing + "\n" + inertia_text + "\n" + commission_text + "\n" + filters)
    return 0


if __name__ == "__main__":
    sys.exit(main())
