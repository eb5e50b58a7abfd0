"""The XTAL bridge: a bpy-free OpenXR client (pyopenxr) that draws BTF scenes straight into
a headset's swapchains with the shared progressive drawer (layer 5: imports core, scene,
render, gl; never bpy). ``bridge.py`` is the API; ``session.py`` the OpenXR resources and
frame loop; ``egl.py`` the headless GL context; ``controls.py`` the controller actions;
``capture.py`` the per-frame EXR + JSON captures."""
