"""blindspot.traj"""
