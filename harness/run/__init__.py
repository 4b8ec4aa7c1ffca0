"""Running things: the plan, the sweep and its process pool, the dt and tolerance ladders, timing, the result store."""
