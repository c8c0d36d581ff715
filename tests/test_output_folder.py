"""A run never deletes what is not its own (io.folder.OutputFolder, docs/failures.md): it
writes only into an empty folder or one an impactfv run made, never through a symbolic link,
never over checkpoints --restart could continue without --overwrite, and every refusal comes
before anything on disk changes. Through the CLI, as a user meets it."""

import os
import shutil

import pytest
from conftest import run_cli

CASE = """
[run]
end_time = 1.0e-6
output_interval = 5.0e-7

[[material]]
name = "copper"
model = "neo_hookean"
density = 8930.0
youngs_modulus = 117.0e9
poisson_ratio = 0.35

[[body]]
name = "block"
material = "copper"
velocity = ["10", "0"]
mesh = { generator = "rectangle", origin = [0, 0], size = [0.01, 0.004], divisions = [10, 4] }
"""


@pytest.fixture
def project(tmp_path):
    (tmp_path / "case.toml").write_text(CASE)
    return tmp_path


def cli(project, *args):
    return run_cli("run", "case.toml", "--no-progress", *args, cwd=project,
                   env={**os.environ, "NUMBA_NUM_THREADS": "1"})


def tree(folder):
    """Every file under ``folder`` with its size and modification time."""
    return {str(p.relative_to(folder)): (p.stat().st_size, p.stat().st_mtime_ns)
            for p in sorted(folder.rglob("*")) if p.is_file()}


def remove(path):
    """Delete the file or folder ``path`` (an output of the run)."""
    if path.is_dir():
        shutil.rmtree(path)
    else:
        path.unlink(missing_ok=True)


def refused(proc, *words):
    lines = proc.stderr.strip().splitlines()
    assert proc.returncode == 2, proc.stderr
    assert len(lines) == 1 and "Traceback" not in proc.stderr, proc.stderr
    for word in words:
        assert word in lines[0], lines[0]


def test_a_refused_option_leaves_the_previous_results(project):
    assert cli(project, "-o", "X").returncode == 0
    before = tree(project / "X")
    for bad in ("1e-20", "1e-300"):
        refused(cli(project, "-o", "X", "--checkpoint-every", bad), "--checkpoint-every")
        assert tree(project / "X") == before


@pytest.mark.parametrize("theirs", ["history.csv", "notes.txt", "plots/figure.png"])
def test_a_folder_impactfv_did_not_make_is_refused_unless_overwrite(project, theirs):
    folder = project / "results_of_someone"
    (folder / theirs).parent.mkdir(parents=True, exist_ok=True)
    (folder / theirs).write_text("kept")
    refused(cli(project, "-o", folder.name), "not empty", "--overwrite")
    assert (folder / theirs).read_text() == "kept"
    assert cli(project, "-o", folder.name, "--overwrite").returncode == 0
    assert (folder / "history.csv").exists()


def test_checkpoints_that_restart_could_use_are_not_deleted_silently(project):
    assert cli(project, "-o", "X", "--checkpoint-every", "5e-7").returncode == 0
    checkpoints = sorted((project / "X" / "checkpoints").glob("checkpoint_*.npz"))
    assert checkpoints
    refused(cli(project, "-o", "X"), "checkpoints", "--restart", "--overwrite")
    assert sorted((project / "X" / "checkpoints").glob("checkpoint_*.npz")) == checkpoints
    # a folder the run made and holding no checkpoints is simply rerun
    assert cli(project, "-o", "X", "--overwrite").returncode == 0
    assert not list((project / "X" / "checkpoints").glob("checkpoint_*.npz"))
    assert cli(project, "-o", "X").returncode == 0


@pytest.mark.parametrize("link", ["plots", "checkpoints", "history.csv"])
def test_nothing_is_written_or_deleted_through_a_symbolic_link(project, link):
    elsewhere = project / "elsewhere"
    elsewhere.mkdir()
    (elsewhere / "keep.png").write_text("kept")
    (elsewhere / "checkpoint_000000001.npz").write_text("kept")
    (elsewhere / "file.csv").write_text("kept")
    assert cli(project, "-o", "X").returncode == 0
    target = elsewhere / "file.csv" if link == "history.csv" else elsewhere
    path = project / "X" / link
    remove(path)
    path.symlink_to(target)
    before = tree(elsewhere)
    for extra in ([], ["--overwrite"]):
        refused(cli(project, "-o", "X", *extra), "symbolic link")
        assert tree(elsewhere) == before


def test_restart_into_another_folder_is_refused(project):
    assert cli(project, "-o", "X", "--checkpoint-every", "5e-7").returncode == 0
    before = tree(project / "X")
    refused(cli(project, "--restart", "X", "-o", "Y"), "--restart", "-o Y")
    refused(cli(project, "--restart", "X", "--overwrite"), "--overwrite")
    assert tree(project / "X") == before
    assert not (project / "Y").exists()


@pytest.mark.parametrize("limit", [1_000, 4_000])
def test_a_file_size_limit_is_a_failed_run_that_keeps_what_it_wrote(project, limit):
    """Writing fails (a file-size limit, as a full disk): exit 3 with one line naming the
    file, no traceback; the files written before stay readable."""
    import resource

    def small_files():
        resource.setrlimit(resource.RLIMIT_FSIZE, (limit, limit))

    proc = run_cli("run", "case.toml", "--no-progress", "-o", "X", cwd=project,
                   env={**os.environ, "NUMBA_NUM_THREADS": "1"}, preexec_fn=small_files)
    assert proc.returncode == 3, proc.stderr
    lines = proc.stderr.strip().splitlines()
    assert len(lines) == 1 and "Traceback" not in proc.stderr, proc.stderr
    assert "writing the outputs failed" in lines[0]
    for path in (project / "X").glob("fields_*.vtu"):
        assert path.stat().st_size > 0


@pytest.mark.parametrize("entry,kind,restart", [
    ("history.csv", "dir", False), ("fields_0003.vtu", "dir", True),
    ("summary.json", "dir", False), ("checkpoints", "file", True),
    ("plots", "file", False), ("history.csv", "dir", True)])
def test_output_entries_of_the_wrong_kind_are_refused(project, entry, kind, restart):
    """A folder where the run writes a file, or a file where it keeps a folder: one line,
    exit 2, nothing changed, for a fresh run and for a restart."""
    assert cli(project, "-o", "X", "--checkpoint-every", "5e-7").returncode == 0
    path = project / "X" / entry
    remove(path)
    if kind == "dir":
        path.mkdir()
    else:
        path.write_text("not a folder")
    before = tree(project / "X")
    args = ["--restart", "X"] if restart else ["-o", "X", "--overwrite"]
    refused(cli(project, *args), entry)
    assert tree(project / "X") == before
