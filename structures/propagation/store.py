"""A resumable Parquet store for propagation results: one file per finished chunk.

Layout of a store directory::

    manifest.json          what the store was made for (fingerprint of the inputs) + format
    part-<chunk>.parquet   the tidy rows of one finished chunk (written whole, then renamed)

A chunk is written to ``.part-<chunk>.parquet.tmp`` and renamed with :func:`os.replace`, which is
atomic on POSIX and Windows: a run killed at any moment leaves either the whole file or none, and
never a half-written ``part-*`` file (temporary files are ignored and removed on the next open).
Rerunning with the same inputs skips the chunks whose file exists; a store made for different
inputs (another posterior, building, record set, scale list, sample count, seed or chunk size) is
refused with a ValueError instead of silently mixing results.
"""

from __future__ import annotations

import json
import os
import uuid
from pathlib import Path

import pandas as pd
import pyarrow as pa
import pyarrow.parquet as pq

FORMAT = "rrfrei-propagation-store/1"
MANIFEST = "manifest.json"


def _write_atomic_bytes(path: Path, data: bytes) -> None:
    tmp = path.with_name(f".{path.name}.{uuid.uuid4().hex}.tmp")
    with open(tmp, "wb") as fh:
        fh.write(data)
        fh.flush()
        os.fsync(fh.fileno())
    os.replace(tmp, path)


class ParquetStore:
    """A directory of per-chunk Parquet files for one set of propagation inputs.

    Parameters
    ----------
    path
        Directory (created if missing).
    fingerprint
        Hex digest of the inputs (see :func:`structures.propagation.propagate.propagate`); compared with the
        manifest of an existing store.
    description
        Human-readable summary of the inputs, stored in the manifest and quoted in the error when
        the fingerprints differ.
    """

    def __init__(self, path: str | os.PathLike, fingerprint: str, description: dict) -> None:
        self.path = Path(path)
        if self.path.exists() and not self.path.is_dir():
            raise ValueError(f"store {str(self.path)!r} exists and is not a directory")
        self.path.mkdir(parents=True, exist_ok=True)
        manifest = self.path / MANIFEST
        if manifest.exists():
            try:
                old = json.loads(manifest.read_text())
            except (OSError, json.JSONDecodeError) as exc:
                raise ValueError(f"store {str(self.path)!r}: unreadable {MANIFEST} ({exc})") from None
            if old.get("format") != FORMAT:
                raise ValueError(
                    f"store {str(self.path)!r} has format {old.get('format')!r}, expected {FORMAT!r}"
                )
            if old.get("fingerprint") != fingerprint:
                differ = sorted(
                    k for k in set(old.get("inputs", {})) | set(description)
                    if old.get("inputs", {}).get(k) != description.get(k)
                )
                raise ValueError(
                    f"store {str(self.path)!r} was made for different inputs "
                    f"(differing: {', '.join(differ) or 'parameter draws or record data'}); "
                    "use another store directory or delete this one"
                )
        elif any(self.path.glob("part-*.parquet")):
            raise ValueError(f"store {str(self.path)!r} has result files but no {MANIFEST}; refusing it")
        else:
            body = {"format": FORMAT, "fingerprint": fingerprint, "inputs": description}
            _write_atomic_bytes(manifest, json.dumps(body, indent=2, sort_keys=True).encode())
        for tmp in self.path.glob(".*.tmp"):  # leftovers of a killed run: never complete files
            tmp.unlink(missing_ok=True)
        self.fingerprint = fingerprint

    def _file(self, chunk_id: str) -> Path:
        return self.path / f"part-{chunk_id}.parquet"

    def done(self) -> set[str]:
        """Ids of the chunks already stored."""
        return {p.name[len("part-"):-len(".parquet")] for p in self.path.glob("part-*.parquet")}

    def write(self, chunk_id: str, frame: pd.DataFrame) -> None:
        """Store the rows of one chunk atomically (temp file, fsync, ``os.replace``)."""
        final = self._file(chunk_id)
        tmp = final.with_name(f".{final.name}.{uuid.uuid4().hex}.tmp")
        table = pa.Table.from_pandas(frame, preserve_index=False)
        pq.write_table(table, tmp)
        with open(tmp, "rb+") as fh:
            os.fsync(fh.fileno())
        os.replace(tmp, final)

    def read(self, chunk_ids: list[str] | None = None) -> pd.DataFrame:
        """Rows of the given chunks (default: all stored chunks), concatenated in that order."""
        ids = sorted(self.done()) if chunk_ids is None else list(chunk_ids)
        frames = [pq.read_table(self._file(c)).to_pandas() for c in ids]
        if not frames:
            return pd.DataFrame()
        return pd.concat(frames, ignore_index=True)
