"""blindspot.bench"""
