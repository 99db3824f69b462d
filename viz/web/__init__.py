"""The live web view (``posed web``): a page on 127.0.0.1 showing what the Zenoh topics carry — the fitted
skeleton in 3D, the joint angles of the last minute, the pipeline's status, fall events with an acknowledge
button and the event history. Never an image: the camera's pixels do not leave the process that captures them.

``hub`` keeps the latest state and fans messages out to the browsers; ``bus`` feeds the hub from a robot
through the Zenoh client (``client.PosedClient``); ``server`` is the HTTP server (standard library,
Server-Sent Events); ``static/`` the page (plain HTML, CSS and JavaScript written for posed, nothing
fetched from a network).
"""
