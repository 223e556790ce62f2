"""What a batch has to do: the videos in a folder, one :class:`ShotJob` per shot.

A job names its shot (``shot_id``, also the name of its output folder), the video and
the frame range to track.  Its *key* is a digest of everything its result depends on —
the video's bytes, the rig, the frame range, the processing options and
``curltrack.__version__`` — so a finished shot with the same key is never redone.
"""

from __future__ import annotations

import hashlib
import json
import os
import re
from collections import Counter
from dataclasses import asdict, dataclass, field
from pathlib import Path

from .. import __version__
from ..errors import InputError

#: File extensions taken for videos (case-insensitive).
VIDEO_EXTENSIONS = (".mp4", ".m4v", ".mov", ".avi", ".mkv", ".mpg", ".mpeg", ".wmv",
                    ".webm", ".mts", ".m2ts", ".3gp")

_CHUNK = 1 << 20


@dataclass(frozen=True)
class BatchOptions:
    """Per-shot processing options (they enter every shot's key).

    Attributes
    ----------
    fixed_stop : bool
        Hold t_F at the detected stop times in the fit (``fit --fixed-stop``).
    discover : bool
        Also run ``discover`` on each shot (writes ``REPORT.json``).
    split : bool
        Segment each video into shots first (``curltrack split``).
    retry_failed : bool
        Redo shots whose input was recorded as unmeasurable (normally skipped while
        their key is unchanged).  Never part of the key.
    plots : bool
        Also write ``FIT.png`` per shot.
    frame_progress : bool
        Workers report the frames they have tracked (for the client's progress bar;
        :data:`curltrack.batch.pipeline.FRAMES_TOPIC`).  Never part of the key.
    """

    fixed_stop: bool = False
    discover: bool = False
    split: bool = False
    retry_failed: bool = False
    plots: bool = False
    frame_progress: bool = False

    def key_items(self) -> dict:
        """The options that change a shot's outputs."""
        return {"fixed_stop": self.fixed_stop, "discover": self.discover,
                "plots": self.plots}


@dataclass(frozen=True)
class ShotJob:
    """One shot to process.

    Attributes
    ----------
    shot_id : str
        Unique, filesystem-safe name; the shot's outputs go to ``OUTDIR/<shot_id>/``.
    video : str
        Absolute path of the video.
    file : str
        The video's path relative to the batch folder (the campaign table's ``file``).
    start_frame, end_frame : int or None
        Frame range to track (release frame .. last frame); None = the whole video.
    shot_index : int or None
        Position of the shot in its video when the video was split (1-based).
    id_note : str or None
        Why ``shot_id`` is not the plain name of the file (two files' names mapped to
        one id); the campaign table's ``shot_id_note``.
    """

    shot_id: str
    video: str
    file: str
    start_frame: int | None = None
    end_frame: int | None = None
    shot_index: int | None = None
    id_note: str | None = None

    def to_dict(self) -> dict:
        return asdict(self)


def find_videos(directory) -> list[Path]:
    """The videos in ``directory`` and its sub-folders, sorted by relative path.

    Hidden files and folders (names starting with ``.``) are left out.

    Raises
    ------
    InputError
        ``directory`` is not a folder.
    """
    directory = Path(directory)
    if not directory.is_dir():
        raise InputError("not a folder (batch expects a folder of videos)", path=directory)
    found = []
    for root, dirs, files in os.walk(directory):
        dirs[:] = sorted(d for d in dirs if not d.startswith("."))
        for name in files:
            if not name.startswith(".") and Path(name).suffix.lower() in VIDEO_EXTENSIONS:
                found.append(Path(root) / name)
    return sorted(found, key=lambda p: p.relative_to(directory).as_posix())


def _safe(text: str) -> str:
    return re.sub(r"[^A-Za-z0-9._-]+", "_", text).strip("._") or "video"


def video_ids(directory, videos) -> dict[Path, str]:
    """A unique, filesystem-safe id for each video: its relative path without extension.

    ``a/b.mp4`` -> ``a__b``; when two videos differ only by extension the extension is
    kept (``b.mp4`` -> ``b_mp4``).  Names that still map to one id (``a b.mp4`` and
    ``a_b.mp4``), also when only their case differs (one folder on a case-insensitive
    file system), get a few hex digits of their relative path's hash: unique by
    construction, and the same on every run.
    """
    directory = Path(directory)
    rel = {v: v.relative_to(directory) for v in videos}
    stems = {v: "__".join(_safe(p) for p in r.with_suffix("").parts) for v, r in rel.items()}
    counts = Counter(stems.values())
    ids = {v: (s if counts[s] == 1 else s + "_" + _safe(rel[v].suffix.lstrip(".")))
           for v, s in stems.items()}
    for n in (6, 12, 64):
        counts = Counter(i.lower() for i in ids.values())
        clash = [v for v, i in ids.items() if counts[i.lower()] > 1]
        if not clash:
            break
        for v in clash:
            digest = hashlib.sha256(rel[v].as_posix().encode()).hexdigest()
            ids[v] = f"{ids[v] if n == 6 else ids[v].rsplit('_', 1)[0]}_{digest[:n]}"
    return ids


def plan_jobs(directory, videos=None) -> list[ShotJob]:
    """One whole-video :class:`ShotJob` per video in ``directory``."""
    directory = Path(directory).resolve()
    videos = [Path(v).resolve() for v in (find_videos(directory) if videos is None else videos)]
    ids = video_ids(directory, videos)
    plain = {v: video_ids(directory, [v])[v] for v in videos}
    jobs = []
    for v in videos:
        note = None
        if ids[v] != plain[v]:
            others = sorted(w.relative_to(directory).as_posix() for w in videos
                            if w != v and plain[w].lower() == plain[v].lower())
            note = (f"{plain[v]!r} is also the name of {', '.join(map(repr, others))}: "
                    "this file's id carries its path's hash")
        jobs.append(ShotJob(ids[v], str(v), v.relative_to(directory).as_posix(),
                            id_note=note))
    return jobs


def split_jobs(job: ShotJob, segments) -> list[ShotJob]:
    """The shots of a split video: ``segments`` is a sequence of (start, end) frames."""
    return [ShotJob(f"{job.shot_id}__shot{i:02d}", job.video, job.file, int(s), int(e), i,
                    job.id_note)
            for i, (s, e) in enumerate(segments, start=1)]


@dataclass
class FileDigest:
    """Content digest of a file with the stat figures it was taken at."""

    sha256: str
    size: int
    mtime_ns: int
    extra: dict = field(default_factory=dict)


def file_digest(path, cached: dict | None = None) -> FileDigest:
    """SHA-256 of a file's bytes (streamed), reusing ``cached`` when size and mtime match.

    ``cached`` is a previous result's ``asdict`` (e.g. from a done-manifest); trusting
    size + modification time the way ``make`` and ``rsync`` do avoids re-reading a
    season of videos on every re-run.

    Raises
    ------
    InputError
        The file cannot be read.
    """
    path = Path(path)
    try:
        st = path.stat()
        if (cached and cached.get("size") == st.st_size
                and cached.get("mtime_ns") == st.st_mtime_ns and cached.get("sha256")):
            return FileDigest(cached["sha256"], st.st_size, st.st_mtime_ns)
        h = hashlib.sha256()
        with open(path, "rb") as fh:
            while chunk := fh.read(_CHUNK):
                h.update(chunk)
    except OSError as exc:
        raise InputError(f"cannot read ({exc.strerror})", path=path) from None
    return FileDigest(h.hexdigest(), st.st_size, st.st_mtime_ns)


def job_key(job: ShotJob, video_sha256: str, rig_text: str, options: BatchOptions) -> str:
    """The digest a finished shot is recognised by (inputs + options + version)."""
    items = {"video": video_sha256, "rig": rig_text, "start_frame": job.start_frame,
             "end_frame": job.end_frame, "options": options.key_items(),
             "version": __version__}
    return hashlib.sha256(json.dumps(items, sort_keys=True).encode()).hexdigest()
