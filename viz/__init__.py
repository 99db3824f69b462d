"""Pictures of what posed found: the overlay video, joint-angle plots, the daily report and the live web view.

Imports numpy, OpenCV, matplotlib (Agg backend only, never a GUI), ``camera_model``, ``fitting``'s and
``falls``' public faces, and nothing of ``daemon``: the commands (``posed render``, ``posed plot``,
``posed report``, ``posed web``) read the files and the databases and hand the values over.

Modules: ``names`` (plain names of the angles), ``skeleton`` (the bones), ``reproject`` (the fitted skeleton
through the fit's camera model), ``draw``, ``overlay`` and ``side_view`` (drawing one frame), ``video`` (the
writer and the progress bar), ``render`` (a clip's frames), ``series`` and ``plots`` (angle trajectories and
fall episodes), ``posture`` and ``report`` (the daily summary), ``web`` (the live page: ``hub``, ``bus``,
``server``, ``static/``). docs/see-it.md describes what each picture shows.
"""
