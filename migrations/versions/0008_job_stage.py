"""jobs.stage, jobs.stage_round: the stage a running job announced and its round (issue 38 item 4)

Revision ID: 0008
Revises: 0007
Create Date: 2026-11-28 01:40:00
"""
from typing import Sequence, Union

import sqlalchemy as sa
from alembic import op

revision: str = '0008'
down_revision: Union[str, None] = '0007'
branch_labels: Union[str, Sequence[str], None] = None
depends_on: Union[str, Sequence[str], None] = None


def upgrade() -> None:
    with op.batch_alter_table('jobs') as batch:
        batch.add_column(sa.Column('stage', sa.String(length=200), nullable=True))
        batch.add_column(sa.Column('stage_round', sa.Integer(), nullable=True))


def downgrade() -> None:
    with op.batch_alter_table('jobs') as batch:
        batch.drop_column('stage_round')
        batch.drop_column('stage')
