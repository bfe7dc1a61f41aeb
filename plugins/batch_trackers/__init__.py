"""Batch trackers: DPNMS, SMOT, CEM, GTCSA-like and ByteTrack over every detection of a video."""
