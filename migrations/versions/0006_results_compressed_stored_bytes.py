"""Results stored compressed (job_results.packed + encoding; data kept for older rows), jobs.stored_bytes
(the bytes a job keeps: usage and the storage quota sum it), an index for retention (issue 27)

Rows written before this revision keep their JSON in ``data`` and are read as they are
(app.runtime.result_codec reads both forms), so the upgrade rewrites no result; it only fills
``stored_bytes`` from the JSON's length in SQL.  The downgrade writes every compressed result back
into ``data`` before dropping the columns, so nothing is lost either way (the codec reads every
encoding it ever wrote, so importing it here stays correct).

Revision ID: 0006
Revises: 0005
Create Date: 2026-11-25 07:10:00
"""
from typing import Sequence, Union

import sqlalchemy as sa
from alembic import op

from app.runtime.result_codec import decode

revision: str = '0006'
down_revision: Union[str, None] = '0005'
branch_labels: Union[str, Sequence[str], None] = None
depends_on: Union[str, Sequence[str], None] = None


def upgrade() -> None:
    with op.batch_alter_table('job_results', schema=None) as batch_op:
        batch_op.add_column(sa.Column('packed', sa.LargeBinary(), nullable=True))
        batch_op.add_column(sa.Column('encoding', sa.String(length=16), nullable=True))
        batch_op.alter_column('data', existing_type=sa.JSON(), nullable=True)
    # recreate='never': on SQLite a batch that copies ``jobs`` drops the old table, and with foreign keys
    # on (app.runtime.db) that DROP deletes every job_results row by ON DELETE CASCADE.  Adding and
    # dropping a plain column and an index are ALTER TABLE statements SQLite has (3.35+).
    with op.batch_alter_table('jobs', schema=None, recreate='never') as batch_op:
        batch_op.add_column(sa.Column('stored_bytes', sa.BigInteger(), server_default='0', nullable=False))
        batch_op.create_index('ix_jobs_status_finished_at', ['status', 'finished_at'], unique=False)
    # what the older rows hold: the params' and the result's JSON text, measured by the database
    if op.get_bind().dialect.name == 'postgresql':
        size = 'octet_length({}::text)'
    else:
        size = 'length(CAST({} AS BLOB))'
    op.execute(f"UPDATE jobs SET stored_bytes = COALESCE({size.format('params')}, 0) + COALESCE("
               f"(SELECT {size.format('r.data')} FROM job_results r WHERE r.job_id = jobs.id), 0)")


def downgrade() -> None:
    conn = op.get_bind()
    results = sa.table('job_results', sa.column('job_id', sa.String), sa.column('data', sa.JSON),
                       sa.column('packed', sa.LargeBinary), sa.column('encoding', sa.String))
    ids = [r.job_id for r in conn.execute(sa.select(results.c.job_id).where(results.c.packed.is_not(None)))]
    for job_id in ids:  # one at a time: results are up to megabytes each
        row = conn.execute(sa.select(results.c.packed, results.c.encoding).where(results.c.job_id == job_id)).one()
        conn.execute(sa.update(results).where(results.c.job_id == job_id).values(
            data=decode(row.packed, row.encoding), packed=None, encoding=None))
    with op.batch_alter_table('jobs', schema=None, recreate='never') as batch_op:  # see upgrade()
        batch_op.drop_index('ix_jobs_status_finished_at')
        batch_op.drop_column('stored_bytes')
    with op.batch_alter_table('job_results', schema=None) as batch_op:
        batch_op.alter_column('data', existing_type=sa.JSON(), nullable=False)
        batch_op.drop_column('encoding')
        batch_op.drop_column('packed')
