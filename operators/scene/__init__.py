"""The scene's data the maps are made from and kept in (docs/architecture.md):

    choices, app_handlers            -- enum items and preferences as values; save/load handlers
    colour_space, images             -- plates into the working space; image pixels in and out
    bounds, floor                    -- screen boxes through the camera; where objects stand
    plate, camera_match              -- the scene's plate; the camera from the photo
    undo_pixels, maps                -- maps' pixels back after undo; map images
    composite                        -- a render over its plate, boxes combined (NumPy)

They import no other room of the add-on.
"""
