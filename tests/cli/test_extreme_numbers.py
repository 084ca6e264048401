"""Extreme and hostile numbers on the command line and in run files (issue 30, BUG-14, -16,
-18, -21): each is one line naming the key or option, the value and the accepted range, exit
2, no traceback, nothing written, and no memory spent on the size it asks for.

Every case is refused before a template is built, so each test takes well under a second;
the two that once allocated without bound (a braid generator of 2^63, a billion replicas)
also run in a child process under a 2 GB address-space limit, so that a regression fails
the test with a MemoryError instead of exhausting the machine.
"""

from __future__ import annotations

import resource
import subprocess
import sys
import textwrap

import pytest

from knotmm.cli.main import main

#: (name, run file text, what the error line must name)
RUN_FILES = [
    ("offset_huge", """
        [[chains]]
        beads = 30
        offset = [1e308, 0.0, 0.0]
        [[chains]]
        beads = 30
        offset = [6.0, 0.0, 0.0]
        """, "chains[0].offset"),
    ("replicas_hugeint", "[run]\nreplicas = 99999999999999999999999999\n", "run.replicas"),
    ("replicas_billion", "[run]\nreplicas = 1000000000\n", "run.replicas"),
    ("duration_400_digits", "[run]\nduration = 1" + "0" * 400 + "\n", "run.duration"),
    ("beads_1e30", "[knot]\nbeads = 1" + "0" * 30 + "\n", "knot.beads"),
    ("helix_huge", '[knot]\nkind = "helix"\nbeads = 40\nhelix_radius = 1e300\n'
                   "helix_pitch = 1e300\n", "knot.helix_radius"),
    ("helix_pitch_huge", '[knot]\nkind = "helix"\nbeads = 40\nhelix_pitch = 1e300\n',
     "knot.helix_pitch"),
    ("arc_denormal", '[knot]\nkind = "arc"\nbeads = 20\narc_degrees = 1e-300\n',
     "knot.arc_degrees"),
    ("link_minor_huge", '[knot]\nkind = "torus"\np = 2\nq = 4\nbeads = 60\n'
                        "minor_radius = 1e300\n", "knot.minor_radius"),
    ("braid_generator_2_63", '[knot]\nkind = "braid"\nword = [9223372036854775807, 1]\n'
                             "beads = 60\n", "knot.word"),
    ("torus_p_huge", "[knot]\np = 1" + "0" * 30 + "\nq = 3\nbeads = 60\n", "knot.p"),
    ("frames_past_dcd", "[run]\nduration = 1e10\n[output]\nframe_interval = 1.0\n",
     "output.frame_interval"),
    ("threads_huge", "[run]\nmobility_threads = 100000\n", "run.mobility_threads"),
    ("rotation_denormal_axis", """
        [[chains]]
        beads = 30
        offset = [-6.0, 0.0, 0.0]
        rotation = [1e-320, 0.0, 0.0, 90.0]
        [[chains]]
        beads = 30
        offset = [6.0, 0.0, 0.0]
        """, "chains[0].rotation"),
]

#: (name, extra `knotmm run` options, what the error line must name)
OVERRIDES = [
    ("peclet_denormal", ["--set", "run.peclet=1e-320"], "run.peclet"),
    ("gravity_huge", ["--set", "model.gravity=1e308"], "model.gravity"),
]


def _one_line(capsys, rc: int, names: str) -> str:
    err = capsys.readouterr().err
    assert rc == 2, err
    assert "Traceback" not in err, err
    lines = err.strip().splitlines()
    assert len(lines) == 1, err
    assert names in lines[0], lines[0]
    return lines[0]


@pytest.mark.parametrize(("name", "text", "names"), RUN_FILES, ids=[c[0] for c in RUN_FILES])
def test_extreme_numbers_in_a_run_file_are_one_line(tmp_path, capsys, name, text, names):
    run_file = tmp_path / f"{name}.toml"
    run_file.write_text(textwrap.dedent(text))
    out = tmp_path / "out"
    rc = main(["run", str(run_file), "--out", str(out), "--no-progress"])
    line = _one_line(capsys, rc, names)
    assert len(line) < 500  # a 400-digit value is cut, not printed whole
    assert not out.exists()  # refused before anything was written


@pytest.mark.parametrize(("name", "options", "names"), OVERRIDES, ids=[c[0] for c in OVERRIDES])
def test_extreme_numbers_on_the_command_line_are_one_line(tmp_path, capsys, name, options,
                                                           names):
    out = tmp_path / "out"
    rc = main(["run", "--beads", "30", "--duration", "1", *options, "--out", str(out),
               "--no-progress"])
    line = _one_line(capsys, rc, names)
    assert "must be" in line  # the accepted range
    assert not out.exists()


def test_range_errors_say_the_limit_and_why(tmp_path, capsys):
    rc = main(["run", "--set", "run.peclet=1e-320", "--out", str(tmp_path / "o")])
    line = _one_line(capsys, rc, "run.peclet = 1e-320")
    assert ">= 2e-10" in line and "kT = 1/Pe" in line
    rc = main(["run", "--set", "model.gravity=1e308", "--out", str(tmp_path / "o")])
    line = _one_line(capsys, rc, "model.gravity = 1e+308")
    assert "<= 100000" in line and "per tau_d" in line


def test_beads_option_with_a_chains_run_file_is_one_line(tmp_path, capsys):
    run_file = tmp_path / "two.toml"
    run_file.write_text(textwrap.dedent("""
        [[chains]]
        beads = 30
        offset = [-4.0, 0.0, 0.0]
        [[chains]]
        beads = 30
        offset = [4.0, 0.0, 0.0]
        """))
    out = tmp_path / "out"
    rc = main(["run", str(run_file), "--beads", "40", "--out", str(out), "--no-progress"])
    line = _one_line(capsys, rc, "--beads 40")
    assert "[[chains]]" in line and "beads = N" in line
    assert not out.exists()


def test_template_with_a_trillion_beads_is_one_line(tmp_path, capsys):
    rc = main(["template", "hopf", "--beads", "1000000000000"])
    line = _one_line(capsys, rc, "knot.beads = 1000000000000")
    assert "<= 99999" in line


def test_movie_dpi_past_the_largest_frame_is_one_line(tmp_path, capsys):
    # the option is checked before the run is read: no run directory is needed
    rc = main(["movie", str(tmp_path / "no_run"), "--dpi", "100000", "--no-progress"])
    line = _one_line(capsys, rc, "--dpi 100000")
    assert "(0, 600]" in line


def _limited(text: str, tmp_path) -> subprocess.CompletedProcess:
    """``knotmm run`` of ``text`` in a child process limited to 2 GB of address space."""
    run_file = tmp_path / "big.toml"
    run_file.write_text(text)

    def limit():
        resource.setrlimit(resource.RLIMIT_AS, (2 * 1024**3, 2 * 1024**3))

    return subprocess.run(
        [sys.executable, "-m", "knotmm.cli", "run", str(run_file), "--out",
         str(tmp_path / "out"), "--no-progress"],
        capture_output=True, text=True, timeout=120, preexec_fn=limit,
    )


@pytest.mark.parametrize("text", [
    '[knot]\nkind = "braid"\nword = [9223372036854775807, 1]\nbeads = 60\n',
    "[knot]\nbeads = 30\n[run]\nreplicas = 1000000000\n",
], ids=["braid_generator_2_63", "replicas_billion"])
def test_sizes_are_bounded_before_memory_is_spent(tmp_path, text):
    done = _limited(text, tmp_path)
    assert done.returncode == 2, done.stderr[-2000:]
    assert "Traceback" not in done.stderr
    assert len(done.stderr.strip().splitlines()) == 1, done.stderr
