"""Helpers shared by the benchmark scripts (imported from the scripts' own folder)."""

import subprocess
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent


def git_state():
    """HEAD commit and whether sorojax/ has uncommitted changes, or None without git."""
    try:
        head = subprocess.run(
            ["git", "rev-parse", "HEAD"],
            cwd=ROOT,
            capture_output=True,
            text=True,
            check=True,
        ).stdout.strip()
        dirty = subprocess.run(
            ["git", "status", "--porcelain", "sorojax"],
            cwd=ROOT,
            capture_output=True,
            text=True,
            check=True,
        ).stdout.rstrip()
        return {"head": head, "sorojax_uncommitted_changes": dirty.splitlines()}
    except (OSError, subprocess.CalledProcessError):
        return None
