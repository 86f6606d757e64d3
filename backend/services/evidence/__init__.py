"""Evidence bundles: a window of what robots logged, as they sent it, with the receipts that carry it, signed
by the server so anyone can check it offline."""
