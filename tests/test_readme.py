"""The README's commands, run as a newcomer would (into temporary folders, never into data/).

Every command the README shows (in a ``bash`` block, or inline as ``python -m helpers ...``) must appear in
:data:`HOW`, which says how it is tested here: quick ones are run in the default suite, long ones under the
``slow`` marker, hardware-only ones by ``--help`` and a ``--dry-run``, and the set-up and test commands by CI
itself (``.ci/run`` runs exactly them). A README edit that adds a command without a test fails
:func:`test_every_readme_command_is_tested`. The pages that took the README's longer sections (:data:`PAGES`)
are held to the same rule, so a command moved out of the README keeps its test. The README itself stays short
(at most :data:`README_BYTES`) and every ``docs/`` page it names exists.
"""

from __future__ import annotations

import json
import os
import re
import shlex
import shutil
import subprocess
import sys
from pathlib import Path

import nbformat
import pytest

from helpers.__main__ import COMMANDS, main
from helpers.base.paths import DATA_DIR, USER_DATA_ENV

REPO_ROOT = Path(__file__).resolve().parents[1]
README = (REPO_ROOT / "README.md").read_text()
PAGES = ("docs/hardware.md", "docs/beyond_the_paper.md", "docs/performance.md", "docs/notebooks.md")
"""The docs/ pages that hold the README's former sections; their commands are tested like the README's."""
README_BYTES = 15_000
"""A README a newcomer reads in ten minutes."""
BIN = Path(sys.executable).parent

MINE = "--v-in 250 --x-f 25 --system zvd --repetitions 3 --group mine"
HOW: dict[str, str] = {
    # set-up and tests: what .ci/run executes on a clean clone
    "python3.11 -m venv .venv": "ci",
    ". .venv/bin/activate": "ci",
    "python -m pip install -r environment.txt": "ci",
    "python -m pytest": "ci",
    "python -m pytest -m slow": "ci",
    # the light environment's check (.ci/run; tests/test_light_install.py runs it without the extras too)
    "python -m helpers metrics data/experiments": "ci",
    "sudo apt-get install -y --no-install-recommends gcc-avr avr-libc arduino-core-avr simavr libsimavr-dev "
    "make gcc g++": "ci",
    # the walkthrough
    "jupyter lab notebooks/": "quick",
    f"python -m helpers record pulse {MINE} --dry-run": "quick",
    f"python -m helpers record pulse {MINE}": "quick",
    "python -m helpers metrics my_data/paper/mine": "quick",
    "python -m helpers metrics my_data/paper/mine --band 0.02 --csv my_data/paper/results/mine --markdown "
    "my_data/paper/results/mine.md": "quick",
    "python -m helpers record calibration": "quick",
    "python -m helpers record identification": "quick",
    # regenerating the shipped data (data/README.md; tests/test_recordings.py and the slow runs of record all)
    "python -m helpers record calibration --data-dir data --replace": "help",
    "python -m helpers record all --data-dir data --replace": "help",
    "python -m helpers record all": "slow",
    "time python -m helpers record all": "slow",
    "python -m helpers reproduce": "slow",
    "python -m helpers reproduce 03": "slow",  # restores a notebook JupyterLab autosaved
    "python -m helpers bench": "slow",
    "python -m helpers bench plant": "slow",
    "python -m helpers bench serial": "slow",
    "python -m helpers bench playground": "slow",
    "python -m helpers record pulse --design data/tuning/designs/<file>.json": "quick",
    "python -m helpers tune": "slow",
    # several tendons: tests/test_tune_tendons.py (a short grid end to end, slow; the dispatch, its refusal)
    "python -m helpers --rig four-tendon tune": "slow",
    "python -m helpers reproduce 07": "slow",
    "python -m helpers record streams": "slow",
    "python -m helpers sweep": "help",
    "python -m helpers sweep atlas": "help",
    "python -m helpers sweep info data/sweeps/atlas_uncertainty.nc": "quick",
    "python -m helpers sweep info my_sweep.nc": "quick",  # test_a_small_sweep_of_ones_own_runs_serially
    "python -m helpers sweep run my_sweep.json --serial": "quick",
    "python -m helpers sweep run my_sweep.json": "slow",
    "python -m helpers sweep run my_sweep.json --scheduler tcp://head:8786": "help",  # and test_sweep.py
    "python -m helpers sweep atlas --overwrite": "help",  # ten minutes; its parts in tests/test_sweep.py
    "python -m helpers sweep atlas --full": "help",
    "python -m helpers bench sweep": "slow",
    "python -m helpers bench spatial": "slow",
    "python -m helpers bench segments": "slow",
    "python -m helpers bench convergence": "slow",
    "python -m helpers bench tune-lanes": "slow",
    "python -m helpers bench tune-tendons-lanes": "slow",
    "python -m helpers virtual-rig frequency-map --preset hanging --directions 0,45 --bends 10": "quick",
    # real and independent data: tests/test_external_dropbear.py::test_the_command_prints_csv_and_notes,
    # tests/test_bare_rod.py::test_the_command_compares_the_twin_with_test_1_within_1_percent (slow)
    "python -m helpers ringdowns data/external/dropbear/10steps_test0.txt": "quick",
    "python -m helpers virtual-rig sorosim data/external/sorosim/SpringSteelRodMuJoCo_1.txt": "slow",
    "python -m helpers rig new my_rig.toml": "quick",  # test_a_new_rig_file_is_written_and_checked
    "python -m helpers rig check my_rig.toml": "quick",
    "python -m helpers rig check long-arm --json": "quick",
    "python -m helpers.rigfile.firmware_header FILE -o rig_config.h": "quick",
    # hardware only, shown as a dry run: test_your_own_rigs_firmware_upload_as_a_dry_run
    "python -m helpers rig firmware my_rig.toml --upload --board daq --port /dev/ttyACM0": "firmware",
    "python -m helpers rig firmware my_rig.toml --dry-run": "firmware",
    # the second rig end to end: tests/test_rig_file_tuning.py::test_second_rig_end_to_end_on_its_twin
    "python -m helpers record calibration --rig long-arm --data-dir my_data": "slow",
    "python -m helpers record all --rig long-arm --data-dir my_data --repetitions 1": "slow",
    "python -m helpers metrics my_data/experiments": "slow",
    "python -m helpers tune --rig long-arm --data-dir my_data --repetitions 1": "slow",
    "python -m helpers virtual-rig tune --rig long-arm --data-dir my_data --out long-arm-tuned.toml": "slow",
    # hardware only: --help and a dry run
    "python -m helpers record calibration --ports auto": "dry-run",
    "python -m helpers record identification --ports auto": "dry-run",
    "python -m helpers record all --ports auto": "dry-run",
    # the hardware day of docs/hardware.md (run whole over serve-virtual-rig: tests/test_hardware_day.py)
    "python -m helpers record table-i --ports auto": "dry-run",
    "python -m helpers tune --ports auto": "help",
    "python -m helpers record pulse --v-in 250 --x-f 25 --system zvd --group mine --ports auto": "dry-run",
    "python -m helpers home --ports auto": "help",
    f"python -m helpers record pulse {MINE} --ports auto --dry-run": "dry-run",
    f"python -m helpers record pulse {MINE} --ports auto": "dry-run",
    "python -m helpers home": "help",
    "python -m helpers home --confirm-slack": "help",
    "python -m helpers serve-virtual-rig": "help",
    "python -m helpers virtual-rig studies": "help",
    # the command line itself
    "python -m helpers": "help",
    "python -m helpers --help": "help",
    "python -m helpers <command> --help": "help",
    "continuum-helpers": "help",
}
"""README command -> how this file tests it."""


def readme_commands(text: str = README) -> list[str]:
    """Every command the README shows: lines of ``bash`` blocks (split at ``&&``) and inline commands."""
    found: list[str] = []
    for block in re.findall(r"```bash\n(.*?)```", text, re.S):
        for line in block.splitlines():
            line = line.split("  #")[0].strip()
            found += [part.strip() for part in line.split("&&") if part.strip()]
    inline = r"`((?:time )?(?:python -m helpers|continuum-helpers)[^`]*)`"
    found += re.findall(inline, text)
    return list(dict.fromkeys(found))


def page(name: str) -> str:
    """The text of a page of :data:`PAGES` (or the README)."""
    return README if name == "README.md" else (REPO_ROOT / name).read_text()


def documented_commands() -> list[str]:
    """Every command of the README and of :data:`PAGES`."""
    return list(dict.fromkeys(c for name in ("README.md", *PAGES) for c in readme_commands(page(name))))


def test_every_readme_command_is_tested():
    commands = readme_commands()
    assert len(commands) >= 15  # the extraction itself works
    untested = [c for c in commands if c not in HOW]
    assert not untested, f"README commands with no test (add them to HOW): {untested}"


@pytest.mark.parametrize("name", PAGES)
def test_every_command_of_the_readmes_former_sections_is_tested(name):
    commands = readme_commands(page(name))
    assert commands, f"{name} shows no command: is it still one of the README's former sections?"
    untested = [c for c in commands if c not in HOW]
    assert not untested, f"{name}: commands with no test (add them to HOW): {untested}"


def test_the_readme_is_read_in_ten_minutes():
    size = len((REPO_ROOT / "README.md").read_bytes())
    assert size <= README_BYTES, f"README.md: {size} bytes, at most {README_BYTES}: move a section to docs/"


def test_every_docs_page_the_readme_names_exists():
    named = set(re.findall(r"\(?(docs/[\w./-]+\.md)", README))
    assert len(named) >= 10  # the index of docs/ by task
    assert set(PAGES) <= named, "the README links every page that holds one of its former sections"
    missing = sorted(n for n in named if not (REPO_ROOT / n).is_file())
    assert not missing, f"the README names docs that do not exist: {missing}"


def test_the_readmes_test_commands_are_what_ci_runs():
    """``.ci/run`` runs exactly the README's two test commands, each on a line of its own."""
    ci = (REPO_ROOT / ".ci" / "run").read_text().splitlines()
    for command in ("python -m pytest", "python -m pytest -m slow"):
        assert command in readme_commands() and command in ci, command
    assert "python -m pip install -q -r environment.txt" in ci  # the README's install, quietly


def test_the_readmes_table_ii_is_notebook_05s():
    """The README's one table is ``figures/table2_vs_paper.md`` (notebook 05), its first ten columns."""
    def rows(text: str) -> list[list[str]]:
        found = [line.strip("|").split("|") for line in text.splitlines() if line.startswith("| v_in_mm_s")]
        body = text.split("| v_in_mm_s", 1)[1].splitlines()[2:]
        found += [line.strip("|").split("|") for line in body if line.startswith("| ")]
        return [[cell.strip() for cell in row[:10]] for row in found]

    table = README.split("## Results", 1)[1].split("\n## ", 1)[0]
    shown, stored = rows(table), rows((REPO_ROOT / "figures" / "table2_vs_paper.md").read_text())
    assert len(shown) == 25 and shown == stored[: len(shown)] and len(stored) == 25


def test_the_number_of_notebooks_is_the_one_stated():
    numbered = sorted((REPO_ROOT / "notebooks").glob("[0-9][0-9]_*.ipynb"))
    first, last = numbered[0].name[:2], numbered[-1].name[:2]
    stated = f"executes the {len(numbered)} notebooks in `notebooks/` ({first}-{last})"
    assert stated in page("docs/notebooks.md")
    listed = re.findall(r"^\| `(\d\d)_\w+` \|", page("docs/notebooks.md"), re.M)
    assert listed == [p.name[:2] for p in numbered], "docs/notebooks.md's table lists every notebook once"


def test_the_pages_the_readme_names_name_existing_docs():
    for name in PAGES:
        named = set(re.findall(r"(docs/[\w./-]+\.md)", page(name)))
        missing = sorted(n for n in named if not (REPO_ROOT / n).is_file())
        assert not missing, f"{name} names docs that do not exist: {missing}"


def _argv(command: str) -> list[str]:
    """The arguments after ``python -m helpers``."""
    words = shlex.split(command)
    assert words[:3] == ["python", "-m", "helpers"], command
    return words[3:]


@pytest.fixture
def newcomer(tmp_path, monkeypatch):
    """A temporary working folder whose data/ holds what a fresh clone has (calibration, identification); the
    user's data folder (``my_data/``) is its own, empty."""
    monkeypatch.setenv(USER_DATA_ENV, str(tmp_path / "my_data"))
    data = tmp_path / "data"
    for group, name in (("calibration", "calibration.json"), ("identification", "result.json")):
        (data / group).mkdir(parents=True)
        shutil.copy(DATA_DIR / group / name, data / group / name)
    monkeypatch.chdir(tmp_path)
    return tmp_path


def _run_in(folder: Path, command: str, *extra: str) -> int:
    """Run a README command with its data folder redirected into ``folder``."""
    argv = _argv(command)
    if argv[0] == "record":
        argv += ["--data-dir", str(folder / "data"), *extra]
    return main(argv)


def test_the_walkthrough_records_and_analyses_an_own_scenario(newcomer, capsys):
    """The README's day as written, in its order, into the user's data folder (here a temporary my_data/):
    calibration, identification, a dry run, the pulses, their metrics; the example output to the digit."""
    shown = documented_commands()
    dry, rec = f"python -m helpers record pulse {MINE} --dry-run", f"python -m helpers record pulse {MINE}"
    metrics = "python -m helpers metrics my_data/paper/mine"
    metrics_files = (f"{metrics} --band 0.02 --csv my_data/paper/results/mine --markdown "
                     "my_data/paper/results/mine.md")  # fmt: skip
    calibration = "python -m helpers record calibration"
    identification = "python -m helpers record identification"
    assert {dry, rec, metrics, metrics_files, calibration, identification} <= set(shown)
    mine = newcomer / "my_data" / "paper"
    assert main(_argv(dry)) == 5  # no calibration yet in my_data/paper: the line names the command
    assert "`python -m helpers record calibration`" in capsys.readouterr().err
    # each README command is a process with a fresh in-process rig; here they share one process, so the steps
    # before the pulses use an instance of their own (the pulses' rig starts as the README's does)
    fresh = ["--virtual-instance", "walkthrough-setup"]
    assert main([*_argv(calibration), *fresh]) == 0
    assert (mine / "calibration" / "load_1900g.json").exists()
    assert main([*_argv(identification), *fresh]) == 0
    assert (mine / "identification" / "result.json").exists()
    assert main(_argv(dry)) == 0
    assert "3 recording(s) would be made" in capsys.readouterr().out
    assert not (mine / "mine").exists()
    assert main(_argv(rec)) == 0
    folder = mine / "mine"
    assert sorted(p.name for p in folder.glob("*.json")) == [f"zvd_v250_x25_r{k}.json" for k in (1, 2, 3)]
    assert main(_argv(metrics)) == 0
    out = capsys.readouterr().out
    assert "zvd (Robust)" in out and "Skipped: none." in out and "virtual-rig" in out
    shown = README.split("Example output (virtual rig):\n\n```text\n")[1].split("```")[0]
    assert shown in out  # the README's example output is what the command prints for these runs
    assert main(_argv(metrics_files)) == 0
    assert (mine / "results" / "mine_runs.csv").exists() and (mine / "results" / "mine.md").exists()
    assert not list((newcomer / "data").rglob("*.csv"))  # nothing recorded into the shipped data's place


@pytest.mark.parametrize("command", [c for c, how in HOW.items() if how == "dry-run"])
def test_hardware_commands_pass_a_dry_run(command, newcomer, capsys):
    extra = [] if "--dry-run" in command else ["--dry-run"]
    assert _run_in(newcomer, command, *extra) == 0
    out = capsys.readouterr().out
    assert "would be made on --ports auto; nothing was sent" in out


@pytest.mark.parametrize("command", sorted({c.split(" --")[0] for c, how in HOW.items() if how == "help"}))
def test_commands_shown_without_a_run_have_help(command, capsys):
    if command == "continuum-helpers":
        script = BIN / "continuum-helpers"
        assert script.exists(), "the console script is not installed (pip install -e .)"
        proc = subprocess.run([str(script), "--help"], capture_output=True, text=True, timeout=60)
        assert proc.returncode == 0 and "reproduce" in proc.stdout
        return
    names = list(COMMANDS) if "<command>" in command else [w for w in _argv(command) if not w.startswith("-")]
    for argv in [[*names[:1], "--help"]] if names else [["--help"]]:
        with pytest.raises(SystemExit) as done:
            main(argv)
        assert done.value.code == 0
    if "<command>" in command:
        for name in COMMANDS:
            with pytest.raises(SystemExit) as done:
                main([name, "--help"])
            assert done.value.code == 0, name
    out = capsys.readouterr().out
    assert "usage: python -m helpers" in out
    for markup in ("``", ":func:", ":class:", ":data:", ":mod:"):  # help is read in a terminal, not rendered
        assert markup not in out, f"{command} --help shows {markup!r}"


def test_a_new_rig_file_is_written_and_checked(newcomer, capsys):
    shown = documented_commands()
    new, check = "python -m helpers rig new my_rig.toml", "python -m helpers rig check my_rig.toml"
    other = "python -m helpers rig check long-arm --json"
    assert {new, check, other} <= set(shown)
    assert main(_argv(new)) == 0 and (newcomer / "my_rig.toml").exists()
    assert main(_argv(check) + ["--points", "2"]) == 0
    assert "predicted modes at rest" in capsys.readouterr().out
    assert main(_argv(other) + ["--points", "2"]) == 0
    assert json.loads(capsys.readouterr().out)["rig"] == "long-arm"
    header = "python -m helpers.rigfile.firmware_header FILE -o rig_config.h"
    assert header in shown
    argv = [sys.executable, "-m", "helpers.rigfile.firmware_header", "my_rig.toml", "-o", "rig_config.h"]
    proc = subprocess.run(argv, cwd=newcomer, capture_output=True, text=True, timeout=120)
    assert proc.returncode == 0, proc.stderr
    assert "#define RIG_MIN_INTERVAL_US 639\n" in (newcomer / "rig_config.h").read_text()


def test_your_own_rigs_firmware_upload_as_a_dry_run(newcomer, capsys):
    """The README's upload of an own rig's firmware, run with ``--dry-run``: the exact avrdude command of the
    Mega (tests/test_rig_firmware_command.py runs the rest; tests/firmware builds for real)."""
    command = "python -m helpers rig firmware my_rig.toml --upload --board daq --port /dev/ttyACM0"
    assert command in documented_commands()
    assert main(["rig", "new", "my_rig.toml"]) == 0
    capsys.readouterr()
    assert main([*_argv(command), "--dry-run"]) == 0
    make, avrdude = capsys.readouterr().out.splitlines()
    assert make.startswith("make -C ") and f"RIG={newcomer / 'my_rig.toml'} " in make
    assert avrdude.startswith("avrdude -p atmega2560 -c wiring -P /dev/ttyACM0 -b 115200 -D -U flash:w:")
    assert avrdude.endswith("/daq_mega.hex:i")


def test_your_own_rigs_firmware_build_as_a_dry_run(newcomer, capsys):
    """The README's build of an own rig's firmware: ``--dry-run`` prints the one make command, with the rig
    file resolved from where the user stands, and no upload."""
    command = "python -m helpers rig firmware my_rig.toml --dry-run"
    assert command in readme_commands()
    assert main(["rig", "new", "my_rig.toml"]) == 0
    capsys.readouterr()
    assert main(_argv(command)) == 0
    (make,) = capsys.readouterr().out.splitlines()
    assert make.startswith("make -C ") and f"RIG={newcomer / 'my_rig.toml'} " in make


def test_jupyter_lab_is_installed_with_the_widget_extension():
    """``jupyter lab`` is in the environment, and so is the extension that draws notebook 03's sliders."""
    import jupyterlab

    assert (BIN / "jupyter-lab").exists() and (BIN / "jupyter").exists()
    assert jupyterlab.__version__.startswith("4.")
    extensions = Path(sys.prefix) / "share" / "jupyter" / "labextensions"
    manager = extensions / "@jupyter-widgets" / "jupyterlab-manager" / "package.json"
    assert manager.exists(), "ipywidgets' JupyterLab extension is missing (pip install -r environment.txt)"
    assert sorted(p.name for p in (REPO_ROOT / "notebooks").glob("0*.ipynb"))[0].startswith("00_")


def test_the_python_examples_run(newcomer, capsys):
    (first,) = re.findall(r"```python\n(.*?)```", README, re.S)
    (second,) = re.findall(r"```python\n(.*?)```", page("docs/beyond_the_paper.md"), re.S)
    exec(compile(first, "README.md", "exec"), {})  # noqa: S102 - the README's own example
    out = capsys.readouterr().out
    assert "overshoot_pct" in out and "Up" in out and "Down" in out
    assert (newcomer / "my_data" / "paper" / "mine" / "zvd_v250_x25_py.json").exists()
    scope: dict = {}
    exec(compile(second, "README.md", "exec"), scope)  # noqa: S102 - the streaming example
    assert scope["rec"].meta["scenario"]["kind"] == "stream" and scope["rec"].status == "complete"
    assert (newcomer / "my_data" / "paper" / "runs" / "my_stream.json").exists()


def test_a_saved_design_runs_again(newcomer, capsys):
    command = "python -m helpers record pulse --design data/tuning/designs/<file>.json"
    assert command in documented_commands()
    design = "map-following_v200_x20.json"
    (newcomer / "data" / "tuning" / "designs").mkdir(parents=True)
    shutil.copy(DATA_DIR / "tuning" / "designs" / design, newcomer / "data" / "tuning" / "designs" / design)
    assert _run_in(newcomer, command.replace("<file>.json", design), "--quiet") == 0
    (saved,) = (newcomer / "data" / "runs").glob("*.json")
    assert '"map-following"' in saved.read_text()


def _my_sweep(folder: Path) -> None:
    """docs/beyond_the_paper.md's sweep definition, written where its commands expect it."""
    (definition,) = re.findall(r"```json\n(.*?)```", page("docs/beyond_the_paper.md"), re.S)
    assert json.loads(definition)["name"] == "my_sweep"
    (folder / "my_sweep.json").write_text(definition)


def test_sweep_info_reads_the_stored_atlas(capsys, monkeypatch):
    monkeypatch.chdir(REPO_ROOT)
    command = "python -m helpers sweep info data/sweeps/atlas_uncertainty.nc"
    assert command in documented_commands()
    assert main(_argv(command)) == 0
    out = capsys.readouterr().out
    assert "sample 64" in out and "shaper 22" in out  # 14 shapers and 8 families at the robust durations


def test_a_small_sweep_of_ones_own_runs_serially(newcomer, capsys):
    command = "python -m helpers sweep run my_sweep.json --serial"
    info = "python -m helpers sweep info my_sweep.nc"
    assert {command, info} <= set(documented_commands())
    _my_sweep(newcomer)
    assert main(_argv(command) + ["--no-progress"]) == 0
    assert "my_sweep: 4 runs" in capsys.readouterr().out and (newcomer / "my_sweep.nc").exists()
    assert main(_argv(info)) == 0
    assert "dimensions: freq_error 2, shaper 2, move 2\n" in capsys.readouterr().out  # as the page lists them
    assert "`freq_error`, `shaper`, `move`, as `python -m helpers sweep info my_sweep.nc`" in " ".join(
        page("docs/beyond_the_paper.md").split()
    )


@pytest.mark.slow
def test_a_small_sweep_on_a_local_cluster(newcomer, capsys):
    command = "python -m helpers sweep run my_sweep.json"
    assert command in documented_commands()
    _my_sweep(newcomer)
    assert main(_argv(command) + ["--no-progress", "--workers", "2"]) == 0
    out = capsys.readouterr().out
    assert "my_sweep: 4 runs" in out and "local Dask cluster of 2 worker(s)" in out


@pytest.mark.slow
def test_record_streams_records_notebook_08s_runs(newcomer):
    (newcomer / "data" / "tuning").mkdir()
    shutil.copy(DATA_DIR / "tuning" / "mode_map.json", newcomer / "data" / "tuning" / "mode_map.json")
    assert _run_in(newcomer, "python -m helpers record streams", "--quiet") == 0
    assert len(list((newcomer / "data" / "streams").glob("*.json"))) == 8


@pytest.mark.slow
def test_record_all_regenerates_the_paper_experiment(newcomer):
    assert _run_in(newcomer, "python -m helpers record all", "--quiet") == 0
    assert len(list((newcomer / "data" / "experiments").glob("*.json"))) == 36
    assert (newcomer / "data" / "identification" / "pulse_v100_x10.json").exists()


@pytest.mark.slow
@pytest.mark.parametrize(
    "suite",
    ["plant", "serial", "sweep", "playground", "spatial", "segments", "convergence", "tune-lanes",
     "tune-tendons-lanes"],
)
def test_bench_prints_its_figures(suite):
    proc = subprocess.run(
        [sys.executable, "-m", "helpers", "bench", suite], capture_output=True, text=True, timeout=3600,
        cwd=REPO_ROOT,
    )  # fmt: skip
    assert proc.returncode == 0, proc.stderr[-2000:]
    printed = ("x real time", "samples", "scaling ratio", "s of CPU", "CPU s per s", "largest |d_peak_n|",
               "runs per CPU second")  # fmt: skip
    assert any(figure in proc.stdout for figure in printed), proc.stdout


@pytest.mark.slow
def test_reproduce_on_a_copy_of_the_repository_changes_no_tracked_file(tmp_path):
    """The README's main command, run twice on a copy of the tracked files: every tracked byte unchanged."""
    files = subprocess.run(
        ["git", "ls-files", "-z"], cwd=REPO_ROOT, capture_output=True, check=True
    ).stdout.decode().split("\0")
    copy = tmp_path / "repo"
    for name in filter(None, files):
        target = copy / name
        target.parent.mkdir(parents=True, exist_ok=True)
        shutil.copy2(REPO_ROOT / name, target)
    before = {n: (copy / n).read_bytes() for n in filter(None, files)}
    env = {k: v for k, v in os.environ.items() if k not in ("HELPERS_FIGURES_DIR", USER_DATA_ENV)}
    env["PYTHONPATH"] = str(copy)
    for _ in range(2):
        proc = subprocess.run(
            [sys.executable, "-m", "helpers", "reproduce"], cwd=copy, env=env, capture_output=True, text=True,
            timeout=900,
        )  # fmt: skip
        assert proc.returncode == 0, proc.stdout[-3000:] + proc.stderr[-3000:]
    changed = [n for n, data in before.items() if (copy / n).read_bytes() != data]
    assert not changed, f"reproduce changed tracked files: {changed}"


def _tracked_copy(target: Path) -> dict[str, bytes]:
    """Copy the tracked files into ``target``; return their bytes by name."""
    files = subprocess.run(
        ["git", "ls-files", "-z"], cwd=REPO_ROOT, capture_output=True, check=True
    ).stdout.decode().split("\0")
    for name in filter(None, files):
        (target / name).parent.mkdir(parents=True, exist_ok=True)
        shutil.copy2(REPO_ROOT / name, target / name)
    return {n: (target / n).read_bytes() for n in filter(None, files)}


def _jupyterlab_autosave(path: Path, widget_cell: int | None = None) -> None:
    """What JupyterLab 4 (ipykernel) writes on its 2-minute autosave, as measured in headless Chromium: the
    kernelspec of the kernel it started; and, for a notebook whose slider cell was run, that cell's widget
    output and the widget state (JupyterLab's "save widget state" setting)."""
    nb = nbformat.read(path, as_version=4)
    spec = {"display_name": "Python 3 (ipykernel)", "language": "python", "name": "python3"}
    nb.metadata["kernelspec"] = spec
    if widget_cell is not None:
        view = {"model_id": "0f3c", "version_major": 2, "version_minor": 0}
        nb.cells[widget_cell].outputs = [nbformat.v4.new_output(
            "display_data",
            data={"application/vnd.jupyter.widget-view+json": view,
                  "text/plain": "interactive(children=(FloatSlider(value=1.2, ...), Output()))"},
        )]  # fmt: skip
        nb.cells[widget_cell].execution_count = 9
        state = {"state": {}, "version_major": 2, "version_minor": 0}
        nb.metadata["widgets"] = {"application/vnd.jupyter.widget-state+json": state}
    nbformat.write(nb, path)


@pytest.mark.slow
def test_reproduce_nn_restores_a_notebook_jupyterlab_autosaved(tmp_path):
    """The README: JupyterLab's autosave rewrites an opened notebook (notebook 03 with its sliders run), and
    ``python -m helpers reproduce 03`` puts back every tracked byte."""
    command = "python -m helpers reproduce 03"
    assert command in readme_commands()
    copy = tmp_path / "repo"
    before = _tracked_copy(copy)
    notebook = "notebooks/03_shaper_design.ipynb"
    _jupyterlab_autosave(copy / notebook, widget_cell=16)
    assert (copy / notebook).read_bytes() != before[notebook]  # the autosave did change it
    env = {k: v for k, v in os.environ.items() if k != "HELPERS_FIGURES_DIR"}
    env["PYTHONPATH"] = str(copy)
    proc = subprocess.run(
        [sys.executable, "-m", "helpers", *_argv(command)], cwd=copy, env=env, capture_output=True,
        text=True, timeout=900,
    )  # fmt: skip
    assert proc.returncode == 0, proc.stdout[-3000:] + proc.stderr[-3000:]
    changed = [n for n, data in before.items() if (copy / n).read_bytes() != data]
    assert not changed, f"reproduce 03 left tracked files changed: {changed}"


@pytest.mark.slow
def test_the_researchers_day_leaves_the_tests_and_reproduce_green_and_the_tree_clean(tmp_path):
    """The README's day on a copy of the repository: own recordings in data/mine and their metrics, the
    notebooks opened and autosaved in JupyterLab (notebook 03's sliders run), ``tune`` into another folder;
    then nbval over every notebook passes, and ``reproduce`` leaves every tracked byte as it was."""
    copy = tmp_path / "repo"
    before = _tracked_copy(copy)
    env = {k: v for k, v in os.environ.items() if k not in ("HELPERS_FIGURES_DIR", USER_DATA_ENV)}
    env["PYTHONPATH"] = str(copy)

    def run(*argv: str, extra_env: dict[str, str] | None = None) -> subprocess.CompletedProcess:
        done = subprocess.run(
            [sys.executable, *argv], cwd=copy, env={**env, **(extra_env or {})}, capture_output=True,
            text=True, timeout=1800,
        )  # fmt: skip
        assert done.returncode == 0, done.stdout[-3000:] + done.stderr[-3000:]
        return done

    run("-m", "helpers", "record", "calibration", "--quiet")  # into the copy's my_data/paper (gitignored)
    run("-m", "helpers", "record", "identification", "--quiet")
    run("-m", "helpers", "record", "pulse", *shlex.split(MINE), "--quiet")
    assert len(list((copy / "my_data" / "paper" / "mine").glob("*.csv"))) == 3
    run("-m", "helpers", "metrics", "my_data/paper/mine", "--band", "0.02", "--csv",
        "my_data/paper/results/mine", "--markdown", "my_data/paper/results/mine.md")  # fmt: skip
    for path in sorted((copy / "notebooks").glob("[0-9][0-9]_*.ipynb")):
        _jupyterlab_autosave(path, widget_cell=16 if path.name.startswith("03_") else None)
    elsewhere = tmp_path / "elsewhere"
    for group, name in (("calibration", "calibration.json"), ("identification", "result.json")):
        (elsewhere / group).mkdir(parents=True)
        shutil.copy(copy / "data" / group / name, elsewhere / group / name)
    run("-m", "helpers", "tune", "--data-dir", str(elsewhere), "--repetitions", "1", "--quiet")
    assert (elsewhere / "tuning" / "tuning_report.png").exists()
    changed = [n for n, data in before.items() if (copy / n).read_bytes() != data]
    assert changed == ["notebooks/03_shaper_design.ipynb"], changed  # only the sliders' output, as saved
    figures = tmp_path / "test-figures"
    figures.mkdir()
    run("-m", "pytest", "notebooks", "-p", "no:cacheprovider", "-q",
        extra_env={"HELPERS_FIGURES_DIR": str(figures)})  # fmt: skip
    run("-m", "helpers", "reproduce")
    changed = [n for n, data in before.items() if (copy / n).read_bytes() != data]
    assert not changed, f"after the researcher's day, reproduce left tracked files changed: {changed}"
