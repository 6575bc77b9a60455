# recon addon, GUI start-up. FreeCAD runs this file with exec(), so names defined here are not globals of the
# methods below: they import what they use.


class ReconWorkbench(Workbench):  # noqa: F821 (FreeCAD defines Workbench before it runs this file)
    MenuText = "Recon"
    ToolTip = "Mesh to CAD: rebuild a triangle mesh as a B-rep solid with recon"

    def __init__(self):
        import recon_addon_gui

        self.__class__.Icon = recon_addon_gui.ICON

    def Initialize(self):
        import recon_addon_gui

        toolbar, menu = recon_addon_gui.register()
        self.appendToolbar("Recon", toolbar)
        self.appendMenu("Recon", menu)

    def GetClassName(self):
        return "Gui::PythonWorkbench"


Gui.addWorkbench(ReconWorkbench())  # noqa: F821
