"""The node trees the maps are read through (docs/architecture.md):

    nodes                            -- small shader-node helpers
    ground_nodes                     -- the ground read per shading point (VR Ground)
    reflection_nodes                 -- the lookup and reflection node groups
    world, world_probe               -- the world look on and off; its HDRI as the on-set probe
    shading                          -- materials on and off, which objects reflect which map

They import the scene's modules (`operators/scene/`), never the other way.
"""
