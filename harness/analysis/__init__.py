"""What the runs mean: orders fitted, work–precision, verdicts, the regression gate, comparisons, the summary.
Data only (tables, dataclasses): rendering is harness.report's."""
