"""
The history of every machine's identifications, without ROS: SQLite by default, PostgreSQL for a fleet.

* :mod:`.records` -- :class:`IdentificationRecord` (one result: machine, data span, speed, method, coefficients with
  sigma and determined flags, physical parameters with sigma, misfit flag, provenance) and its content key.
* :mod:`.schema`  -- the tables (SQLAlchemy 2 Core), the schema version and its migrations.
* :mod:`.store`   -- :class:`HistoryStore`: write (idempotent, one writer per machine), query, machines.
"""
from .records import (Coefficient, COEFFICIENT_NAMES, coefficients_from_arrays, IdentificationRecord, Parameter,
                      record_from_result)
from .schema import SCHEMA_VERSION, SchemaVersionError
from .store import HistoryStore, Machine, redacted_url, sqlite_url, WriterConflict, WriteResult

__all__ = ['COEFFICIENT_NAMES', 'Coefficient', 'coefficients_from_arrays', 'IdentificationRecord', 'Parameter',
           'record_from_result',
           'SCHEMA_VERSION', 'SchemaVersionError', 'HistoryStore', 'Machine', 'redacted_url', 'sqlite_url',
           'WriteResult',
           'WriterConflict']
