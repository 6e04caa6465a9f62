"""The grid world: mazes, layouts, obstacles, the 3D scenes and the rendered pictures."""
