"""VR in Blender: the 'XR' draw callback of Blender's own VR session (``preview.py``, its
per-draw costs in ``live.py``), its panel, settings and the Custom Overlays switch
(``panel.py``, ``scene.btf_vr``), the VR controllers' action map and
operator (``actions.py``), the XTAL Bridge operator (``xtal_bridge.py``, ``xr/bridge.py`` on its
own thread) and the Stereo Capture operator (``stereo_capture.py``)."""
