"""A git worktree of a commit, for the scripts that run two trees side by
side (bench_parallel.py, compare_answers.py)."""
import os
import subprocess
import tempfile

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))


def worktree(commit):
    """The path of a detached worktree of ``commit`` (made once, under the temporary directory)."""
    path = os.path.join(tempfile.gettempdir(), f"pimpm-baseline-{commit}")
    if not os.path.isdir(path):
        subprocess.run(["git", "-C", ROOT, "worktree", "add", "--detach", path, commit], check=True,
                       stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
    return path
