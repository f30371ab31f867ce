// Placeholder until the cfgmgr commands land.
int main() { return 0; }
