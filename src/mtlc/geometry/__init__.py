"""Equipment geometry: the meshes of a scene's models and solids, in the scene frame, and
the distances from the body's capsules to them.

Below the semantics layer: it knows numpy (and trimesh, imported only when a model file is
read; coal, for distances), not the language. ``model`` holds the placed geometry, ``load``
reads mesh files, ``solids`` builds the language's boxes, cylinders and plates, ``distance``
measures capsules against meshes and ``clearance`` per frame and per goal.
"""
