"""The perception bounds' steps in the chain's order (the keys of safety_bound.json and
safety_held_out_bound.json, :data:`blindspot.safety.bound.BOUNDS`) with the words the README and
the report pages give each: what a perfect decision knows from the first frame of each piece of
information about the lead child. ``{m}``, ``{n}``: the M of N of the confirmation."""

__all__ = ["BOUND_STEPS"]

BOUND_STEPS = (("line_of_sight", "its first frame in line of sight"),
               ("radar_point", "its first radar point"),
               ("confirmed_track", "a track confirmed on {m} of {n} frames of its points"))
