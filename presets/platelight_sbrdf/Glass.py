import bpy
node = bpy.context.material.node_tree.nodes['PlateLight SBRDF']
node.inputs['Diffuse Albedo'].default_value = (1.0, 1.0, 1.0, 1.0)
node.inputs['Specular Albedo'].default_value = (0.04, 0.04, 0.04, 1.0)
node.inputs['Glossiness'].default_value = 1.0
node.inputs['Cx'].default_value = -1.0
node.inputs['Cy'].default_value = -1.0
node.inputs['Cz'].default_value = 1.0
node.inputs['Fresnel Falloff'].default_value = 0.16666666666666666
node.inputs['Tangent Rotation'].default_value = 0.0
node.inputs['Anisotropy'].default_value = 0.0
node.inputs['Emission Color'].default_value = (1.0, 1.0, 1.0, 1.0)
node.inputs['Emission Strength'].default_value = 0.0
node.inputs['Alpha'].default_value = 0.0
node.inputs['IOR'].default_value = 1.5
node.inputs['Dispersion'].default_value = 0.01
node.inputs['Retro-Reflection'].default_value = 0.0
node.inputs['Paper Falloff'].default_value = 0.0
