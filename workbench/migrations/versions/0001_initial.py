"""Initial schema: units, calibration sets, approvals, sessions, results.

Revision ID: 0001
Revises:
Create Date: 2026-11-22
"""

import sqlalchemy as sa
from alembic import op

revision = "0001"
down_revision = None
branch_labels = None
depends_on = None


def upgrade() -> None:
    op.create_table(
        "units",
        sa.Column("serial", sa.String(128), primary_key=True),
        sa.Column("model", sa.String(128), nullable=False),
        sa.Column("created", sa.String(40), nullable=False),
    )
    op.create_table(
        "calibration_sets",
        sa.Column("id", sa.String(64), primary_key=True),
        sa.Column("serial", sa.String(128), sa.ForeignKey("units.serial"), nullable=False),
        sa.Column("version", sa.Integer, nullable=False),
        sa.Column("created", sa.String(40), nullable=False),
        sa.Column("procedures", sa.Text, nullable=False),
        sa.Column("sha256", sa.String(64), nullable=False),
        sa.Column("body", sa.Text, nullable=False),
        sa.UniqueConstraint("serial", "version", name="uq_set_serial_version"),
    )
    op.create_index("ix_calibration_sets_serial", "calibration_sets", ["serial"])
    op.create_table(
        "approvals",
        sa.Column("set_id", sa.String(64), sa.ForeignKey("calibration_sets.id"), primary_key=True),
        sa.Column("approved_by", sa.String(128), nullable=False),
        sa.Column("approved_at", sa.String(40), nullable=False),
        sa.Column("comment", sa.Text, nullable=False),
    )
    op.create_table(
        "sessions",
        sa.Column("id", sa.String(64), primary_key=True),
        sa.Column("serial", sa.String(128), sa.ForeignKey("units.serial"), nullable=False),
        sa.Column("procedure", sa.String(64), nullable=False),
        sa.Column("path", sa.Text, nullable=False),
        sa.Column("created", sa.String(40), nullable=False),
        sa.Column("sha256", sa.String(64), nullable=False),
        sa.Column("n_steps", sa.Integer, nullable=False),
        sa.Column("complete", sa.Boolean, nullable=False),
    )
    op.create_index("ix_sessions_serial", "sessions", ["serial"])
    op.create_table(
        "results",
        sa.Column("id", sa.Integer, primary_key=True, autoincrement=True),
        sa.Column("procedure", sa.String(64), nullable=False),
        sa.Column("session_id", sa.String(64), nullable=False),
        sa.Column("serial", sa.String(128), nullable=False),
        sa.Column("calibration_id", sa.String(64), nullable=True),
        sa.Column("created", sa.String(40), nullable=False),
        sa.Column("body", sa.Text, nullable=False),
    )
    for col in ("procedure", "session_id", "serial"):
        op.create_index(f"ix_results_{col}", "results", [col])


def downgrade() -> None:
    for table in ("results", "sessions", "approvals", "calibration_sets", "units"):
        op.drop_table(table)
