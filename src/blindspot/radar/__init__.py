"""blindspot.radar"""
