"""bpy-free controller devices (the Wiimote over hidapi's hidraw) and the generic action API."""
