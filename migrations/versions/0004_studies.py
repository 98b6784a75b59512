"""studies: trade studies (a base job swept over parameters); jobs.study_id/study_index

Revision ID: 0004
Revises: 0003
Create Date: 2026-11-22 23:00:00
"""
from typing import Sequence, Union

import sqlalchemy as sa
from alembic import op

revision: str = '0004'
down_revision: Union[str, None] = '0003'
branch_labels: Union[str, Sequence[str], None] = None
depends_on: Union[str, Sequence[str], None] = None


def upgrade() -> None:
    op.create_table('studies',
    sa.Column('id', sa.String(length=32), nullable=False),
    sa.Column('kind', sa.String(length=32), nullable=False),
    sa.Column('label', sa.String(length=200), nullable=True),
    sa.Column('preset', sa.String(length=100), nullable=True),
    sa.Column('mode', sa.String(length=16), nullable=False),
    sa.Column('status', sa.String(length=16), nullable=False),
    sa.Column('base_params', sa.JSON(), nullable=False),
    sa.Column('sweeps', sa.JSON(), nullable=False),
    sa.Column('points', sa.JSON(), nullable=False),
    sa.Column('walk', sa.JSON(), nullable=False),
    sa.Column('owner', sa.String(length=100), nullable=True),
    sa.Column('queue', sa.String(length=32), server_default='trajlab.jobs', nullable=False),
    sa.Column('cancel_requested', sa.Boolean(), nullable=False),
    sa.Column('created_at', sa.DateTime(timezone=True), nullable=False),
    sa.Column('finished_at', sa.DateTime(timezone=True), nullable=True),
    sa.PrimaryKeyConstraint('id', name=op.f('pk_studies'))
    )
    with op.batch_alter_table('studies', schema=None) as batch_op:
        batch_op.create_index('ix_studies_owner_created_at', ['owner', 'created_at'], unique=False)
    with op.batch_alter_table('jobs', schema=None) as batch_op:
        batch_op.add_column(sa.Column('study_id', sa.String(length=32), nullable=True))
        batch_op.add_column(sa.Column('study_index', sa.Integer(), nullable=True))
        batch_op.create_index('ix_jobs_study_id', ['study_id'], unique=False)
        batch_op.create_foreign_key(batch_op.f('fk_jobs_study_id_studies'), 'studies', ['study_id'], ['id'],
                                    ondelete='SET NULL')


def downgrade() -> None:
    with op.batch_alter_table('jobs', schema=None) as batch_op:
        batch_op.drop_constraint(batch_op.f('fk_jobs_study_id_studies'), type_='foreignkey')
        batch_op.drop_index('ix_jobs_study_id')
        batch_op.drop_column('study_index')
        batch_op.drop_column('study_id')
    with op.batch_alter_table('studies', schema=None) as batch_op:
        batch_op.drop_index('ix_studies_owner_created_at')
    op.drop_table('studies')
