"""The shipped default templates (``default.json``), written by `cbgo train dynamic`.

A package only so that the JSON file is installed with the code (package data).
"""
