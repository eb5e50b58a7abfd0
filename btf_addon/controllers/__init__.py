"""bpy-free controller devices and the generic action API.

- ``transport.py``: the one small interface every device stream goes through (write bytes;
  read with a timeout → bytes or None) and the errors a user can act on.
- ``hid_transport.py``: a real Wiimote through hidapi (``hidraw`` on Linux, ``hid`` elsewhere).
- ``replay.py``: the JSONL recording format, the replay transport and the recorder.
- ``wiimote/``: the Wiimote protocol, one module per feature (as Linux hid-wiimote) and a
  non-blocking driver over a transport.
- ``actions.py``, ``bindings.py``, ``controls.py``: the action vocabulary, bindings as data and
  the step function (time, controller state) → edits.
"""
