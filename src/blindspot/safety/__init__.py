"""blindspot.safety: from predicted paths to a decision.

Collision risk of each track's predicted distribution against the ego car's swept footprint,
time to collision, the warning and AEB model (latency, braking ramp) and the scenario metrics
scored as Euro NCAP does. Reads tracks and predictions; report reads its artifacts
(``.importlinter``).
"""
