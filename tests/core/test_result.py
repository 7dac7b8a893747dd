"""The result protocol (workbench/result.py): structural checks and summary lines."""

from workbench.result import AnalysisResult, CoefficientResult, SummaryLines


class _Plain:
    warnings = ("w",)

    def to_dict(self):
        return {}

    def summary(self):
        return ["line"]


class _WithCoefficients(_Plain):
    def to_calibration(self, unit):
        return None


def test_protocols_check_the_methods():
    assert isinstance(_Plain(), AnalysisResult) and not isinstance(_Plain(), CoefficientResult)
    assert isinstance(_WithCoefficients(), CoefficientResult)
    assert not isinstance(object(), AnalysisResult)


def test_summary_lines_are_a_list_and_callable():
    lines = SummaryLines(["a", "b"])
    assert lines == ["a", "b"] and lines() == ["a", "b"]
    assert type(lines()) is list  # a plain copy
    out = lines()
    out.append("c")
    assert lines == ["a", "b"]
