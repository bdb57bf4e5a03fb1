"""Virtual EUMOS 40509 acceleration bench for pallet loads wrapped in stretch paper or film."""
