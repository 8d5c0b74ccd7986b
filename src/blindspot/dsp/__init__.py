"""blindspot.dsp"""
