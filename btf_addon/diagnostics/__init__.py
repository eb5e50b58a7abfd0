"""Environment probes (bpy, OpenCL, EGL, HID, OpenXR, OpenEXR), each run in its own subprocess
by the doctor so a crashing driver cannot take the caller down. Used by the CLI's ``doctor``
and by Blender's "Check System" operator, so it sits below both."""
