"""``python -m tumblecal_cli`` runs the same CLI as the ``tumblecal`` console script."""

from tumblecal_cli.cli import main_exit

main_exit()
