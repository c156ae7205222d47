"""Equipment geometry: the meshes of a scene's models and solids, in the scene frame.

Below the semantics layer: it knows numpy (and trimesh, imported only when a model file is
read), not the language. ``model`` holds the placed geometry, ``load`` reads mesh files,
``solids`` builds the language's boxes, cylinders and plates.
"""
