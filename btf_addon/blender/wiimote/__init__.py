"""The Wiimote in Blender: the modal operator (``operator.py``) over a session that polls the
driver (``session.py``), what each action changes in the scene (``edits.py``, shared by the VR
controllers and the XTAL bridge), the pointer's ray (``pointer.py``), the help overlay
(``overlay.py``) and the bindings in the add-on's preferences (``preferences.py``)."""
