// Placeholder until the dcf2concise commands land.
int main() { return 0; }
