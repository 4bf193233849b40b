"""
The history database's tables (SQLAlchemy 2 Core), its version, and the migrations from older versions.

One schema for SQLite and PostgreSQL.  SI units in every value column (speed [rad/s], coefficients [N/m], [N s/m],
clearance [m], viscosity [Pa s], times [s since the UNIX epoch]); NaN is stored as NULL (SQLite cannot store NaN)
and read back as NaN.

Versions:

* 1 -- ``schema_version``, ``machines``, ``identifications`` (without ``provenance``) and ``coefficients``.
* 2 -- adds ``identifications.provenance`` (JSON text), ``parameters`` (fitted physical parameters) and ``writers``
  (the one-writer-per-machine lease).

:func:`migrate` upgrades an older database in place, one step per version, inside the caller's transaction; a newer
one is refused (:class:`SchemaVersionError`): this code would not know what it is writing into.
"""
from __future__ import annotations

import sqlalchemy as sa

SCHEMA_VERSION = 2

metadata = sa.MetaData()

schema_version = sa.Table(
    'schema_version', metadata,
    sa.Column('version', sa.Integer, nullable=False),
)

machines = sa.Table(
    'machines', metadata,
    sa.Column('machine_id', sa.String(200), primary_key=True),
    sa.Column('rig_name', sa.String(200), nullable=False, server_default=''),
    sa.Column('created', sa.Double, nullable=False),                     # [s, UNIX]
)

identifications = sa.Table(
    'identifications', metadata,
    sa.Column('id', sa.Integer, primary_key=True, autoincrement=True),
    sa.Column('machine_id', sa.String(200), sa.ForeignKey('machines.machine_id'), nullable=False),
    sa.Column('result_key', sa.String(64), nullable=False),
    sa.Column('t_start', sa.Double, nullable=False),                     # [s, UNIX]
    sa.Column('t_end', sa.Double, nullable=False),                       # [s, UNIX]
    sa.Column('speed', sa.Double, nullable=False),                       # [rad/s]
    sa.Column('method', sa.String(40), nullable=False),
    sa.Column('misfit', sa.Boolean, nullable=False),
    sa.Column('written', sa.Double, nullable=False),                     # [s, UNIX]
    sa.Column('provenance', sa.Text, nullable=False, server_default='{}'),   # JSON (version 2)
    sa.UniqueConstraint('machine_id', 'result_key', name='uq_identifications_machine_key'),
)
sa.Index('ix_identifications_machine_time', identifications.c.machine_id, identifications.c.t_end)

coefficients = sa.Table(
    'coefficients', metadata,
    sa.Column('identification_id', sa.Integer, sa.ForeignKey('identifications.id'), primary_key=True),
    sa.Column('bearing', sa.String(200), primary_key=True),
    sa.Column('name', sa.String(8), primary_key=True),                   # Kxx Kxy Kyx Kyy Cxx Cxy Cyx Cyy
    sa.Column('value', sa.Double),                                       # [N/m] or [N s/m]; NULL = NaN
    sa.Column('sigma', sa.Double),
    sa.Column('determined', sa.Boolean, nullable=False),
)

parameters = sa.Table(
    'parameters', metadata,
    sa.Column('identification_id', sa.Integer, sa.ForeignKey('identifications.id'), primary_key=True),
    sa.Column('bearing', sa.String(200), primary_key=True),
    sa.Column('name', sa.String(60), primary_key=True),                  # clearance [m], viscosity [Pa s], k_scale [-]
    sa.Column('value', sa.Double),
    sa.Column('sigma', sa.Double),
)

writers = sa.Table(
    'writers', metadata,
    sa.Column('machine_id', sa.String(200), sa.ForeignKey('machines.machine_id'), primary_key=True),
    sa.Column('token', sa.String(64), nullable=False),                   # the holder's random id
    sa.Column('host', sa.String(255), nullable=False),
    sa.Column('pid', sa.Integer, nullable=False),
    sa.Column('acquired', sa.Double, nullable=False),                    # [s, UNIX]
    sa.Column('heartbeat', sa.Double, nullable=False),                   # [s, UNIX]
)


class SchemaVersionError(RuntimeError):
    """The database's schema version is newer than this code's, or not a version it knows."""


def _v1_to_v2(conn: sa.Connection) -> None:
    conn.execute(sa.text("ALTER TABLE identifications ADD COLUMN provenance TEXT NOT NULL DEFAULT '{}'"))
    metadata.create_all(conn, tables=[parameters, writers])


MIGRATIONS = {1: _v1_to_v2}     # from version -> the step to the next


def read_version(conn: sa.Connection) -> int | None:
    """Return the database's schema version, None when it has no history tables yet."""
    if not sa.inspect(conn).has_table('schema_version'):
        return None
    rows = conn.execute(sa.select(schema_version.c.version)).scalars().all()
    if len(rows) != 1:
        raise SchemaVersionError(f'the schema_version table must hold one row, it holds {len(rows)}')
    return int(rows[0])


def migrate(conn: sa.Connection, url: str = '') -> int:
    """
    Create the schema, or upgrade an older one in place, on ``conn`` (inside its transaction); return the old version.

    Old version 0 means a new database.  Raises :class:`SchemaVersionError` for a newer or unknown version.
    """
    version = read_version(conn)
    if version is None:
        metadata.create_all(conn)
        conn.execute(schema_version.insert().values(version=SCHEMA_VERSION))
        return 0
    if version > SCHEMA_VERSION:
        raise SchemaVersionError(
            f'history database {url or conn.engine.url!r} has schema version {version}, newer than this bearing_id '
            f'understands ({SCHEMA_VERSION}): upgrade bearing_id to read or write it (nothing was changed)')
    old = version
    while version < SCHEMA_VERSION:
        step = MIGRATIONS.get(version)
        if step is None:
            raise SchemaVersionError(f'history database {url!r}: no migration from schema version {version}')
        step(conn)
        version += 1
    if old != version:
        conn.execute(schema_version.update().values(version=version))
    return old
