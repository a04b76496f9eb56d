"""nbvkit's version, here so that the modules below the package (nbvkit.runfolder's manifest)
read it without importing the package (whose __init__ imports everything)."""

__version__ = "0.1.0"
