"""The pipeline layer: what `stereodyn run` does, in order (phases.py: its phases as declared steps, each with its
inputs and outputs: truths and sweep -> ladders -> advice -> verdicts -> What to use -> report), and the runs that the
ladders, the advice and the verdicts need (dt_ladders, tolerance_ladders, advice, checks; work_precision: the ladders
and advice phases). analysis/ decides which runs those are and reads their tables; it runs nothing. Above report and
below cli (tests/test_layers.py)."""
