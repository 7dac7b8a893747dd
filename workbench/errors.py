"""Exception family of the workbench.

Every error a user can cause derives from :class:`WorkbenchError` and carries a one-line
message that names the file, column, step or field at fault. The command line and the
dashboard catch :class:`WorkbenchError` once, print the message and exit non-zero.
"""

from __future__ import annotations


class WorkbenchError(Exception):
    """Base class: a user-facing error with a one-line message."""


class CalibrationFormatError(WorkbenchError):
    """A calibration-set file or object is malformed (bad JSON, shape, value, version)."""


class SessionError(WorkbenchError):
    """A session (manifest or samples) is malformed or cannot support the analysis."""


class RigLimitError(WorkbenchError):
    """A sequence asks the rig for something outside its limits."""


class StoreError(WorkbenchError):
    """The store cannot be opened, read or written."""


class AnalysisError(WorkbenchError):
    """An analysis cannot produce a trustworthy result from its input."""


class ProcedureError(WorkbenchError):
    """An unknown procedure, or a procedure that does not apply to the unit."""


class ExportError(WorkbenchError):
    """An unknown export format, or a set that the format cannot express."""


class ImportProfileError(WorkbenchError):
    """An import profile is malformed or does not match the file it is applied to."""


class RigError(WorkbenchError):
    """A rig (simulated or real) failed: no answer, an error reply, an interlock."""
