"""The GUI side of the recon addon: the "Mesh to CAD (recon)" command, its task panel (the report, the faces, the
deviation map) and the setting of where recon's Python lives. The work itself is :mod:`recon_addon`."""

from __future__ import annotations

import os

import FreeCAD
import FreeCADGui

import recon_addon

ICON = os.path.join(os.path.dirname(os.path.abspath(__file__)), "Resources", "icons", "recon.svg")
MESH_FILTER = "Meshes (*.stl *.obj *.ply *.off *.3mf *.glb);;All files (*)"


def _qt():
    from PySide import QtCore, QtGui  # FreeCAD's PySide shim: QtGui holds the widgets too

    return QtCore, QtGui


class MeshToCadCommand:
    """Convert the selected Mesh objects (or a mesh file chosen) into B-rep solids with recon."""

    def GetResources(self):
        return {
            "Pixmap": ICON,
            "MenuText": "Mesh to CAD (recon)",
            "ToolTip": "Rebuild the selected mesh (or a mesh file) as a solid of planes, cylinders, fillets and "
            "B-splines with recon, with its faces named and coloured by kind",
        }

    def IsActive(self):
        return True

    def Activated(self):
        QtCore, QtGui = _qt()
        meshes = [o for o in FreeCADGui.Selection.getSelection() if o.isDerivedFrom("Mesh::Feature")]
        sources = list(meshes)
        if not sources:
            path, _ = QtGui.QFileDialog.getOpenFileName(None, "Mesh to CAD (recon): choose a mesh", "", MESH_FILTER)
            if not path:
                return
            sources = [path]
        doc = FreeCAD.ActiveDocument or FreeCAD.newDocument("recon")
        for source in sources:
            result = _run_with_progress(doc, source)
            if result is None:
                return
            if not isinstance(source, str) and source.ViewObject is not None:
                source.ViewObject.Visibility = False  # the solid takes the mesh's place on screen
        FreeCADGui.SendMsgToActiveView("ViewFit")
        FreeCADGui.Control.closeDialog()
        FreeCADGui.Control.showDialog(ReportPanel(result))


def _run_with_progress(doc, source):
    QtCore, QtGui = _qt()
    name = source if isinstance(source, str) else source.Label
    dialog = QtGui.QProgressDialog(f"recon is converting {os.path.basename(name)}…", "Stop", 0, 0)
    dialog.setWindowTitle("Mesh to CAD (recon)")
    dialog.setWindowModality(QtCore.Qt.WindowModal)
    dialog.show()

    def poll():
        QtGui.QApplication.processEvents()
        return not dialog.wasCanceled()

    try:
        return recon_addon.mesh_to_cad(doc, source, poll=poll)
    except recon_addon.ReconAddonError as exc:
        QtGui.QMessageBox.critical(None, "Mesh to CAD (recon)", str(exc))
        return None
    finally:
        dialog.close()


class ReportPanel:
    """The task panel: recon's verdict and figures, the faces (click a row to select the face), and the colouring:
    by kind (recon's colours) or by deviation (the mesh's distance to each face against the tolerance)."""

    def __init__(self, result):
        QtCore, QtGui = _qt()
        self.result = result
        report = result.run.report
        self.form = QtGui.QWidget()
        self.form.setWindowTitle("recon report")
        layout = QtGui.QVBoxLayout(self.form)
        lines = recon_addon.summary_lines(report)
        good = (report.get("verdict") or {}).get("within_tolerance")
        colour = "#1a7f37" if good else "#b42318"
        text = f"<b style='color:{colour}'>{_html(lines[0])}</b><br>" + "<br>".join(_html(s) for s in lines[1:])
        label = QtGui.QLabel(text)
        label.setWordWrap(True)
        layout.addWidget(label)
        row = QtGui.QHBoxLayout()
        self.by_kind = QtGui.QRadioButton("colour by kind")
        self.by_dev = QtGui.QRadioButton("by deviation (blue 0 → red 2T)")
        self.by_kind.setChecked(True)
        self.by_kind.toggled.connect(self._recolour)
        row.addWidget(self.by_kind)
        row.addWidget(self.by_dev)
        layout.addLayout(row)
        self.table = self._table(QtGui, recon_addon.face_rows(result.faces, report))
        layout.addWidget(self.table)

    def _table(self, QtGui, rows):
        heads = ("face", "name", "surface", "mesh→shape max", "shape→mesh max")
        table = QtGui.QTableWidget(len(rows), len(heads))
        table.setHorizontalHeaderLabels(list(heads))
        for i, r in enumerate(rows):
            cells = (r[0], r[1], r[3], _fmt(r[6]), _fmt(r[7]))
            for j, value in enumerate(cells):
                table.setItem(i, j, QtGui.QTableWidgetItem(str(value)))
        table.resizeColumnsToContents()
        table.setSelectionBehavior(QtGui.QAbstractItemView.SelectRows)
        table.setEditTriggers(QtGui.QAbstractItemView.NoEditTriggers)
        table.itemSelectionChanged.connect(self._select)
        table.setMinimumHeight(320)
        return table

    def _select(self):
        feature = self.result.feature
        FreeCADGui.Selection.clearSelection()
        for index in sorted({i.row() for i in self.table.selectedIndexes()}):
            FreeCADGui.Selection.addSelection(feature, f"Face{index + 1}")

    def _recolour(self, *_):
        if self.by_kind.isChecked():
            colours = self.result.colours
        else:
            colours = recon_addon.deviation_colours(self.result.faces, self.result.run.report)
        recon_addon.apply_colours(self.result.feature, colours)

    def getStandardButtons(self):
        _, QtGui = _qt()
        return int(QtGui.QDialogButtonBox.Close)

    def reject(self):
        FreeCADGui.Control.closeDialog()
        return True

    accept = reject


def _fmt(x):
    return "" if x is None else f"{x:.3g}"


def _html(s):
    return s.replace("&", "&amp;").replace("<", "&lt;").replace(">", "&gt;")


class SettingsCommand:
    """Choose the Python of recon's environment (the setting ReconPython)."""

    def GetResources(self):
        return {"MenuText": "Where recon lives…", "ToolTip": "Choose the python of the environment where recon is "
                "installed (empty: the recon command on PATH)"}

    def IsActive(self):
        return True

    def Activated(self):
        _, QtGui = _qt()
        current = recon_addon.params().GetString("ReconPython", "")
        path, _ = QtGui.QFileDialog.getOpenFileName(
            None, "The python of recon's environment (Cancel: use recon on PATH)", current or os.path.expanduser("~")
        )
        recon_addon.params().SetString("ReconPython", path or "")
        try:
            where = " ".join(recon_addon.recon_command())
        except recon_addon.ReconAddonError as exc:
            where = str(exc)
        FreeCAD.Console.PrintMessage(f"recon: runs as {where}\n")


def register():
    """Add the commands to FreeCAD (once)."""
    if "Recon_MeshToCad" not in FreeCADGui.listCommands():
        FreeCADGui.addCommand("Recon_MeshToCad", MeshToCadCommand())
        FreeCADGui.addCommand("Recon_Settings", SettingsCommand())
    return ["Recon_MeshToCad"], ["Recon_MeshToCad", "Recon_Settings"]
