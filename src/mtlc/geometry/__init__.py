"""Geometry of the equipment the manikin works on: meshes, distances."""
