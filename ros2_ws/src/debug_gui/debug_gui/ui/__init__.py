"""The browser side (NiceGUI): the registry of view kinds, the shell, one module per kind.

Every module in this folder that registers a view kind is imported by the server
(:func:`debug_gui.ui.registry.load_views`), so a new view needs no edit elsewhere.
"""
