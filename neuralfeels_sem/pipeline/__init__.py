"""Runs that combine the layers below: a sensor's frames through perception and the mapper,
scored by eval, with the run outputs of docs/design.md. Built from objects, never from a
config: the tasks compose the config, instantiate and call (layer order: docs/design.md)."""
