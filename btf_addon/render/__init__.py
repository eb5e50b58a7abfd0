"""bpy-free render drivers: the render settings as plain values, light selection for a frame,
progressive-lighting state and the final render's launch planning. No device code: the
back ends (cl/, gl/) are driven from here."""
