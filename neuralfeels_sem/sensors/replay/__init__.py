"""Recordings: writer/reader of the task=record layout, ReplaySensor, FeelSight reader and exporter."""
