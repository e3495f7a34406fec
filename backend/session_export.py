"""A session's samples as files engineers open in their own tools: CSV (a header row of unit-named columns) and
Parquet (typed columns, the session's facts as file metadata). pyarrow writes the Parquet; the csv module the CSV."""

from __future__ import annotations

import csv
import io


def samples_csv(columns: dict[str, list]) -> bytes:
    """One row per sample, the columns in their stored order; empty cells for nulls."""
    out = io.StringIO(newline="")
    writer = csv.writer(out, lineterminator="\n")
    names = list(columns)
    writer.writerow(names)
    writer.writerows(zip(*(columns[n] for n in names), strict=True))
    return out.getvalue().encode("utf-8")


def samples_parquet(columns: dict[str, list], facts: dict[str, str]) -> bytes:
    """The same columns as a Parquet file; ``facts`` (strings) stored as its key-value metadata under ``quasitune.``."""
    import pyarrow as pa
    import pyarrow.parquet as pq

    table = pa.table({n: pa.array(v) for n, v in columns.items()})
    table = table.replace_schema_metadata({f"quasitune.{k}": v for k, v in facts.items()})
    sink = io.BytesIO()
    pq.write_table(table, sink)
    return sink.getvalue()
