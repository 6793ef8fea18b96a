"""voxgi viewer: moderngl renderer, glfw window, headless snapshots.

The walkthrough and the progressive preview arrive with the bake file; what
is here now is the headless GL context every later part renders through.
"""
