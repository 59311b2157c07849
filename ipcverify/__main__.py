"""``python -m ipcverify`` runs the command-line interface."""

from ipcverify.cli import main

main()
