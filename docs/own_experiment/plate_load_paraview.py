"""Draw docs/own_experiment/plate_load_clumps.png from a plate_load run's snapshots (ParaView's
pvpython, headless: ``xvfb-run -a pvpython docs/own_experiment/plate_load_paraview.py RUN PNG``):
the last snapshot's grains as spheres of their true radius coloured by ``clump_id``, the steel
plate (the boxes block) and the floor and back walls translucent."""

import sys

from paraview.simple import (ColorBy, GetActiveViewOrCreate, GetAnimationScene, GetColorTransferFunction,
                             SaveScreenshot, Show, Xdmf3ReaderS)

run, png = sys.argv[1], sys.argv[2]
grains = Xdmf3ReaderS(FileName=[f"{run}/snapshots.xmf"])
scene = GetAnimationScene()
scene.UpdateAnimationUsingDataTimeSteps()
scene.AnimationTime = grains.TimestepValues[-1]
view = GetActiveViewOrCreate("RenderView")
view.OrientationAxesVisibility = 0
view.Background = [1.0, 1.0, 1.0]
try:
    view.UseColorPaletteForBackground = 0
except AttributeError:  # ParaView before 5.10
    pass
g = Show(grains, view)
g.SetRepresentationType("Point Gaussian")
g.ShaderPreset = "Sphere"
g.ScaleByArray = 1
g.SetScaleArray = ["POINTS", "radius"]
g.UseScaleFunction = 0
g.GaussianRadius = 1.0
ColorBy(g, ("POINTS", "clump_id"))
lut = GetColorTransferFunction("clump_id")
lut.ApplyPreset("Rainbow Uniform", True)
g.SetScalarBarVisibility(view, False)
plate = Show(Xdmf3ReaderS(FileName=[f"{run}/snapshots_boxes.xmf"]), view)
ColorBy(plate, None)
plate.AmbientColor = plate.DiffuseColor = [0.55, 0.57, 0.6]
plate.Opacity = 0.85
walls = Show(Xdmf3ReaderS(FileName=[f"{run}/snapshots_walls.xmf"]), view)
ColorBy(walls, None)
walls.AmbientColor = walls.DiffuseColor = [0.75, 0.75, 0.75]
walls.Opacity = 0.12
view.CameraPosition = [0.75, -0.65, 0.55]
view.CameraFocalPoint = [0.15, 0.15, 0.05]
view.CameraViewUp = [0.0, 0.0, 1.0]
view.ResetCamera()
SaveScreenshot(png, view, ImageResolution=[1000, 750])
