"""Code generated from the project's MAVLink dialect (wire/codecs/dpgw.xml) by tools/generate_dialect.py.

Do not edit: regenerate. Use it through :mod:`wire.codecs.mavlink`.
"""
