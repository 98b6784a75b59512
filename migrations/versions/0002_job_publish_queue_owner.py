"""jobs: published_at (re-publisher), queue (quick/heavy), owner (API keys)

Revision ID: 0002
Revises: 0001
Create Date: 2026-11-22 22:50:00
"""
from typing import Sequence, Union

import sqlalchemy as sa
from alembic import op

revision: str = '0002'
down_revision: Union[str, None] = '0001'
branch_labels: Union[str, Sequence[str], None] = None
depends_on: Union[str, Sequence[str], None] = None


def upgrade() -> None:
    with op.batch_alter_table('jobs', schema=None) as batch_op:
        batch_op.add_column(sa.Column('published_at', sa.DateTime(timezone=True), nullable=True))
        batch_op.add_column(sa.Column('queue', sa.String(length=32), server_default='trajlab.jobs', nullable=False))
        batch_op.add_column(sa.Column('owner', sa.String(length=100), nullable=True))
        batch_op.create_index('ix_jobs_owner_created_at', ['owner', 'created_at'], unique=False)
    # Jobs stored before this revision were published when they were submitted.
    op.execute("UPDATE jobs SET published_at = created_at")


def downgrade() -> None:
    with op.batch_alter_table('jobs', schema=None) as batch_op:
        batch_op.drop_index('ix_jobs_owner_created_at')
        batch_op.drop_column('owner')
        batch_op.drop_column('queue')
        batch_op.drop_column('published_at')
