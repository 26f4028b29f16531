"""Data contracts: Arrow schemas of the Parquet tables, the descriptor's JSON Schema and its dataclasses."""

from schemas.tables import (
    INGEST_VERSION,
    MARKERS_SCHEMA,
    OBJECT_MODEL_SCHEMA,
    POSES_SCHEMA,
    SCHEMA_VERSION,
)

__all__ = ["INGEST_VERSION", "MARKERS_SCHEMA", "OBJECT_MODEL_SCHEMA", "POSES_SCHEMA", "SCHEMA_VERSION"]
