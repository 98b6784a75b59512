"""leases: the recovery loop's lease (holder, expiry), so its duties run in every worker and exactly one
holds them (issue 27 item 6); the row named ``recovery`` is made here, free

Revision ID: 0007
Revises: 0006
Create Date: 2026-11-25 07:30:00
"""
from datetime import datetime, timezone
from typing import Sequence, Union

import sqlalchemy as sa
from alembic import op

revision: str = '0007'
down_revision: Union[str, None] = '0006'
branch_labels: Union[str, Sequence[str], None] = None
depends_on: Union[str, Sequence[str], None] = None


def upgrade() -> None:
    leases = op.create_table(
        'leases',
        sa.Column('name', sa.String(length=64), nullable=False),
        sa.Column('holder', sa.String(length=200), nullable=True),
        sa.Column('acquired_at', sa.DateTime(timezone=True), nullable=True),
        sa.Column('renewed_at', sa.DateTime(timezone=True), nullable=True),
        sa.Column('expires_at', sa.DateTime(timezone=True), nullable=False),
        sa.PrimaryKeyConstraint('name', name=op.f('pk_leases')),
    )
    # the row exists from the start, so taking the lease is always one conditional UPDATE
    op.bulk_insert(leases, [{'name': 'recovery', 'holder': None, 'acquired_at': None, 'renewed_at': None,
                             'expires_at': datetime(1970, 1, 1, tzinfo=timezone.utc)}])


def downgrade() -> None:
    op.drop_table('leases')
