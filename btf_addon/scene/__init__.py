"""The plain-array scene (bpy-free): meshes per corner, camera, Blender's lights in Cycles'
units, materials, tangents, the BVH, and the analysis of which effects a scene calls for.

What ``blender/export*`` produces from a depsgraph and every renderer consumes."""
