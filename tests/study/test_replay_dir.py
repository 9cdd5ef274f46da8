"""The default folder of a replay: one per (run, method), the same every time."""

from __future__ import annotations

import hashlib

from sensorplan.study.replay import replay_dir_name


def test_methods_that_spell_alike_get_folders_of_their_own() -> None:
    names = ["a b", "a_b", "a/b", "a:b", "a b ", " a b", "", "_", "OLF pg K=3", "OLF_pg_K_3"]
    folders = [replay_dir_name(3, n) for n in names]
    assert len(set(folders)) == len(names), folders
    assert all(f.startswith("run-00003-") and "/" not in f and " " not in f for f in folders)


def test_the_folder_is_the_name_or_the_name_with_its_digest() -> None:
    assert replay_dir_name(7, "pg") == "run-00007-pg"
    assert replay_dir_name(7, "a_b") == "run-00007-a_b"
    # An independent spelling of the documented rule: stable across processes and versions.
    digest = hashlib.sha256(b"OLF sequential-greedy K=3").hexdigest()[:6]
    assert replay_dir_name(0, "OLF sequential-greedy K=3") == \
        f"run-00000-OLF_sequential-greedy_K_3-{digest}" == \
        "run-00000-OLF_sequential-greedy_K_3-09e94f"
