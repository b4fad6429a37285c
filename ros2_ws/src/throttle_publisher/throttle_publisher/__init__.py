"""Throttling messages at the publisher, so that each subscriber gets only the rate it asked for.

Will hold the throttling publisher and its examples (thesis section 4.2); later work fills it in.
"""
