"""blindspot: FMCW radar detection and path prediction of pedestrians hidden behind parked cars."""

__version__ = "0.1.0"
