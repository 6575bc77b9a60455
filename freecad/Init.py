# recon addon: nothing to set up without the GUI. Headless use: import recon_addon (this folder is on sys.path once
# FreeCAD loads the addon) and call recon_addon.mesh_to_cad(doc, mesh_feature_or_path).
