"""The XTAL bridge: a bpy-free OpenXR client (pyopenxr) that draws BTF scenes straight into
a headset's swapchains with the shared progressive drawer (layer 5: imports core, scene,
render, gl; never bpy, nor its sibling controllers/). ``bridge.py`` is the API; ``session.py``
the OpenXR resources, state machine and frame loop (its data in ``views.py``); ``egl.py`` the
headless GL context, ``desktop_gl.py`` the context per binding kind, ``bindings.py`` the
binding structs; ``controls.py`` the controller actions; ``capture.py`` the per-frame EXR +
JSON captures; ``errors.py`` the errors and their exit codes."""
