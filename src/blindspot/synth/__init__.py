"""blindspot.synth: turns scenes into measured data sets.

The one room that may join radar (scenes, simulator), dsp (the detection chain) and traj (path
data sets): detection over simulated scenes, paths measured through the chain, the path data set.
radar, dsp, traj and report never import it (checked by the import contracts in
``.importlinter``).
"""
