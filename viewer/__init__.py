"""voxgi viewer: a bake (`voxbake bake`) in a glfw window or in headless
snapshots (docs/design.md section 9).

camera.py (pure maths, explicit dt), renderer.py (takes a moderngl
context), snapshot.py (standalone EGL), window.py (glfw: the only import of
it), cli.py (`voxview`).
"""
